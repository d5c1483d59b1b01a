"""A sample of the malformed-input sweep (cbnet_lab/fuzz_inputs.py, run
by tools/analysis_tools/fuzz_inputs.py): every mutation kind that once
crashed or was silently lost, plus a few others, through dataset +
pipeline + one training step, each with the outcome it must have (a
clear error raised by our checks and naming the file, a drop logged per
reason, or a normal training step; never silent, never a crash)."""
import json

import pytest
from tool_helpers import load_tool

from cbnet_lab import fuzz_inputs

#: Mutation -> its expected outcome. 'clear error': raised by the package's
#: own checks (not a library error) and naming the mutated file.
EXPECTED = {
    'bbox_string': 'clear error',  # box not 4 numbers
    'bbox_wrong_length': 'clear error',
    'bbox_nan': 'clear error',  # box not finite
    'iscrowd_all': 'clear error',  # no training image left
    'no_annotations': 'clear error',  # no training image left
    'key_images_missing': 'clear error',  # not COCO format
    'json_truncated': 'clear error',  # not valid JSON
    'json_top_level_list': 'clear error',
    'segm_empty_list': 'clear error',
    'segm_rle_garbage': 'clear error',  # undecodable RLE
    'segm_rle_wrong_size': 'clear error',  # RLE size != image size
    'img_smaller_than_ann': 'clear error',  # image size != annotation's
    'img_truncated': 'clear error',  # cannot decode
    'img_grey': 'ok',  # read as 3 channels
    'many_tiny_instances': 'ok',  # 200 1-pixel boxes train fine
    # once silent (labels shifted or permuted, instances lost, ignore
    # regions made, garbage masks) or a crash (segfault, 22 GB, assert)
    'categories_reversed': 'ok',  # labels by name
    'class_absent': 'ok',  # no label shifts
    'category_missing_first': 'logged drop',
    'category_missing_used': 'logged drop',
    'category_unknown': 'logged drop',
    'image_id_dangling': 'logged drop',
    'bbox_outside_image': 'logged drop',
    'bbox_below_1px': 'logged drop',
    'area_zero': 'logged drop',
    'duplicate_image_id': 'clear error',
    'image_id_string': 'clear error',
    'ann_image_id_string': 'clear error',
    'duplicate_ann_id': 'clear error',
    'iscrowd_string': 'clear error',
    'rle_counts_short': 'clear error',
    'bbox_mask_mismatch': 'clear error',
    'polygon_huge': 'clear error',
    'polygon_nan': 'clear error',
    'foggy_twin_empty': 'clear error',  # paired dataset: names the twin
    'foggy_twin_truncated': 'clear error',
}


def load_fuzz_tool():
    """The command line (the sweep itself is cbnet_lab.fuzz_inputs)."""
    return load_tool('analysis_tools/fuzz_inputs.py')


@pytest.mark.slow  # ~60 s on 2 cores (35 variants, ~11 training steps)
def test_fuzz_sample_outcome_per_mutation(cityscapes_like_root, tmp_path):
    fuzz = fuzz_inputs
    sample = sorted(EXPECTED)
    assert set(sample) <= set(fuzz.MUTATIONS)
    result = fuzz.sweep(cityscapes_like_root, len(sample), seed=0,
                        num_images=2, scale=(128, 64),
                        work=str(tmp_path), mutations=sample)
    assert result['tried'] == len(sample)
    got = {name: outcomes for name, outcomes in
           result['per_mutation'].items()}
    assert got == {name: {outcome: 1} for name, outcome in EXPECTED.items()
                   }, (result['crashes'], result['silent'])
    assert result['outcomes']['silent'] == result['outcomes']['crash'] == 0
    table = fuzz.markdown(result)
    assert ('| mutation | tried | ok | logged drop | clear error | silent '
            '| crash |') in table
    o = result['outcomes']
    assert (f'| **total** | {len(sample)} | {o["ok"]} | {o["logged drop"]} '
            f'| {o["clear error"]} | 0 | 0 |') in table


def _variant_dataset(fuzz, root, tmp_path, mutation):
    import numpy as np
    from mmdet.registry import DATASETS
    from mmengine.config import Config
    from mmengine.registry import init_default_scope
    init_default_scope('mmdet')
    ann_file, _ = fuzz.make_variant(root, str(tmp_path), mutation, 2,
                                    np.random.default_rng(0))
    cfg = Config.fromfile(fuzz.DEMO).train_dataloader.dataset.dataset
    cfg.update(data_root=root, ann_file=ann_file,
               data_prefix=dict(img='leftImg8bit/train/'))
    return DATASETS.build(cfg), ann_file


def test_audit_counts_unlogged_loss_and_changed_labels(cityscapes_like_root,
                                                       tmp_path):
    """What the sweep scores as 'silent': an annotation gone without a
    count, an image gone, a label changed."""
    fuzz = fuzz_inputs
    ds, ann_file = _variant_dataset(fuzz, cityscapes_like_root, tmp_path,
                                    'area_zero')
    prefix = ds.data_prefix['img']
    assert fuzz.audit(ds, ann_file, prefix) == []
    assert sum(ds.load_report['drops'].values()) == 1
    ds.load_report['drops'] = {}  # as if dropped without a log line
    problems = fuzz.audit(ds, ann_file, prefix)
    assert len(problems) == 1 and problems[0].endswith(
        'annotations not loaded, 0 logged as dropped and 0 left out by '
        'filter_cfg'), problems
    ds.load_report['filtered_images'] += 1  # an image gone uncounted
    assert 'images not loaded' in fuzz.audit(ds, ann_file, prefix)[-1]
    # labels: the file says otherwise than what was loaded
    with open(ann_file) as f:
        coco = json.load(f)
    cats = coco['categories']
    cats[0]['name'], cats[2]['name'] = cats[2]['name'], cats[0]['name']
    with open(ann_file, 'w') as f:
        json.dump(coco, f)
    assert any(p.startswith('loaded instance matches no annotation')
               for p in fuzz.audit(ds, ann_file, prefix))


def test_classify_counts_only_our_errors_that_name_the_file(tmp_path):
    from mmengine.fileio import load

    from cbnet_mmdet.datasets import CBNetCityscapesDataset
    classify = fuzz_inputs.classify
    missing = str(tmp_path / 'missing.json')
    with pytest.raises(FileNotFoundError) as library:
        load(missing)  # raised inside Python/mmengine, names the file
    assert missing in str(library.value)
    assert classify(library.value, missing, missing) == 'crash'
    with pytest.raises(FileNotFoundError) as ours:
        CBNetCityscapesDataset(ann_file=missing, pipeline=[])
    assert classify(ours.value, missing, missing) == 'clear error'
    other = str(tmp_path / 'other.json')
    assert classify(ours.value, other, other) == 'crash'  # names no file
    assert classify(RuntimeError(missing), missing, missing) == 'crash'


def test_fuzz_command_line(tmp_path, monkeypatch, capsys):
    """The documented command (two quick mutations): table, summary line,
    JSON with the count per outcome."""
    fuzz = load_fuzz_tool()
    out = tmp_path / 'fuzz.json'
    monkeypatch.setattr('sys.argv', [
        'fuzz_inputs.py', '--variants', '2', '--mutations', 'json_truncated',
        'iscrowd_string', '--out', str(out)
    ])
    fuzz.main()
    printed = capsys.readouterr().out
    assert ('2 inputs tried: 0 ok, 0 logged drop, 2 clear error, 0 silent, '
            '0 crash;') in printed
    assert '| iscrowd_string | 1 | 0 | 0 | 1 | 0 | 0 |' in printed
    result = json.loads(out.read_text())
    assert result['outcomes'] == {'ok': 0, 'logged drop': 0,
                                  'clear error': 2, 'silent': 0, 'crash': 0}
