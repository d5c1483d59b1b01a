"""A sample of the malformed-input sweep (tools/analysis_tools/
fuzz_inputs.py): every mutation kind that once crashed, plus a few others,
through dataset + pipeline + one training step, each with the outcome it
must have (a clear error raised by our checks and naming the file, or a
normal training step)."""
import importlib.util
import os.path as osp

import pytest

from tiny_configs import REPO

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
    'segm_empty_list': 'clear error',
    'segm_rle_garbage': 'clear error',  # undecodable RLE
    'segm_rle_wrong_size': 'clear error',  # RLE size != image size
    'img_smaller_than_ann': 'clear error',  # image size != annotation's
    'img_truncated': 'clear error',  # cannot decode
    'img_grey': 'ok',  # read as 3 channels
    'many_tiny_instances': 'ok',  # 200 1-pixel boxes train fine
}


def load_fuzz_tool():
    spec = importlib.util.spec_from_file_location(
        'cbnet_tools_fuzz_inputs',
        osp.join(REPO, 'tools', 'analysis_tools', 'fuzz_inputs.py'))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow  # ~30 s on 2 cores (14 variants, ~6 training steps)
def test_fuzz_sample_outcome_per_mutation(cityscapes_like_root, tmp_path):
    fuzz = load_fuzz_tool()
    sample = sorted(EXPECTED)
    assert set(sample) <= set(fuzz.MUTATIONS)
    result = fuzz.sweep(cityscapes_like_root, len(sample), seed=0,
                        num_images=2, scale=(128, 64),
                        work=str(tmp_path), mutations=sample)
    assert result['tried'] == len(sample)
    got = {name: outcomes for name, outcomes in
           result['per_mutation'].items()}
    assert got == {name: {outcome: 1}
                   for name, outcome in EXPECTED.items()}, result['crashes']
    table = fuzz.markdown(result)
    assert f'| **total** | {len(sample)} |' in table


def test_classify_counts_only_our_errors_that_name_the_file(tmp_path):
    from mmengine.fileio import load

    from cbnet_mmdet.datasets import CBNetCityscapesDataset
    classify = load_fuzz_tool().classify
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
