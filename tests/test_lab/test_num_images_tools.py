"""``--num-images N`` of tools/test.py and ap_drop.py: the first N images
scored against their own ground truth, the same numbers as a full run on a
set made of exactly those images; ``indices`` with a whole-file metric is
refused.

The model is the oracle of ``conftest.py`` leaving out the first two
instances of each foggy image (beta 0.02): AP and mIoU below 100, so
ground truth of images not tested (counted as missed) would show.
"""
import json
import os.path as osp

import pytest
from mmengine.config import Config
from tool_helpers import load_tool

ANN = 'annotations/instancesonly_filtered_gtFine_val.json'
FOGGY = ['test_dataloader.dataset.type=CBNetFoggyCityscapesDataset',
         'test_dataloader.dataset.beta=0.02']


def only_these_images(root: str, num: int, target: str) -> str:
    """The val annotations of the first ``num`` images, written by hand
    (the independent reference set)."""
    with open(osp.join(root, ANN)) as f:
        coco = json.load(f)
    ids = [img['id'] for img in coco['images'][:num]]
    coco['images'] = coco['images'][:num]
    coco['annotations'] = [a for a in coco['annotations']
                           if a['image_id'] in ids]
    with open(target, 'w') as f:
        json.dump(coco, f)
    return target


def metric_values(metrics: dict) -> dict:
    return {k: v for k, v in metrics.items()
            if k.startswith(('coco/', 'cityscapes/')) and 'copypaste' not in k}


@pytest.fixture
def foggy_oracle(make_oracle, tmp_path):
    """The oracle's config, test-only (tools/test.py builds a Runner of
    the whole config)."""
    oracle = make_oracle({'0.02': 2})
    cfg = Config.fromfile(oracle['cfg_file'])
    for key in ('train_dataloader', 'val_dataloader', 'val_evaluator',
                'val_cfg'):
        cfg.pop(key, None)
    oracle['cfg_file'] = str(tmp_path / 'oracle_test_cfg.py')
    cfg.dump(oracle['cfg_file'])
    return oracle


def test_test_py_num_images_equals_a_set_of_those_images(
        foggy_oracle, cityscapes_like_root, tmp_path, restore_environ):
    tool = load_tool('test.py')
    cfg_file, ckpt = foggy_oracle['cfg_file'], foggy_oracle['ckpt']
    quick = tool.main([cfg_file, ckpt, '--num-images', '2', '--work-dir',
                       str(tmp_path / 'quick'), '--cfg-options'] + FOGGY)
    seen = [p for p, _ in foggy_oracle['seen']]
    assert len(seen) == 2
    # reference: the full run on a set made of the same two images
    ann = only_these_images(cityscapes_like_root, 2,
                            str(tmp_path / 'two.json'))
    foggy_oracle['seen'].clear()
    full = tool.main([
        cfg_file, ckpt, '--work-dir', str(tmp_path / 'full'),
        '--cfg-options', f'test_dataloader.dataset.ann_file={ann}',
        f'test_evaluator.0.ann_file={ann}',
        f'test_evaluator.1.ann_file={ann}'] + FOGGY)
    assert [p for p, _ in foggy_oracle['seen']] == seen
    quick, full = metric_values(quick), metric_values(full)
    assert quick == full
    assert 0 < quick['coco/bbox_mAP'] < 1 and 0 < quick['coco/segm_mAP'] < 1
    assert 0 < quick['cityscapes/mIoU'] < 100
    # what was written: the two images' annotations, pointed at by the
    # dataset and both evaluators
    written = tmp_path / 'quick' / 'first_2_images'
    files = sorted(p.name for p in written.iterdir())
    assert len(files) == 1, files
    with open(written / files[0]) as f:
        assert json.load(f) == json.load(open(ann))


def test_test_py_refuses_indices_scored_against_the_whole_file(
        foggy_oracle, tmp_path, restore_environ):
    tool = load_tool('test.py')
    with pytest.raises(ValueError, match='indices=2 tests a subset.*'
                       'scores against every image.*--num-images'):
        tool.main([foggy_oracle['cfg_file'], foggy_oracle['ckpt'],
                   '--work-dir', str(tmp_path / 'w'), '--cfg-options',
                   'test_dataloader.dataset.indices=2'])
    assert foggy_oracle['seen'] == []  # refused before testing
    with pytest.raises(ValueError, match='not both'):
        tool.main([foggy_oracle['cfg_file'], foggy_oracle['ckpt'],
                   '--num-images', '1', '--work-dir', str(tmp_path / 'w'),
                   '--cfg-options', 'test_dataloader.dataset.indices=2'])
    with pytest.raises(ValueError, match='holds 3 images'):
        tool.main([foggy_oracle['cfg_file'], foggy_oracle['ckpt'],
                   '--num-images', '4', '--work-dir', str(tmp_path / 'w')])


def test_ap_drop_num_images_equals_a_set_of_those_images(
        foggy_oracle, cityscapes_like_root, tmp_path):
    tool = load_tool('analysis_tools/ap_drop.py')
    cfg_file, ckpt = foggy_oracle['cfg_file'], foggy_oracle['ckpt']
    quick = tool.main([cfg_file, ckpt, '--betas', '0.02', '--num-images',
                       '2', '--out-dir', str(tmp_path / 'quick')])
    ann = only_these_images(cityscapes_like_root, 2,
                            str(tmp_path / 'two.json'))
    cfg = Config.fromfile(cfg_file)
    cfg.test_dataloader.dataset.ann_file = ann
    for evaluator in cfg.test_evaluator:
        if 'ann_file' in evaluator:  # not the official Cityscapes metric
            evaluator.ann_file = ann
    cfg.dump(str(tmp_path / 'two_cfg.py'))
    full = tool.main([str(tmp_path / 'two_cfg.py'), ckpt, '--betas', '0.02',
                      '--out-dir', str(tmp_path / 'full')])
    assert quick['rows'] == full['rows']
    assert quick['metrics'] == full['metrics']
    foggy = quick['rows'][1]
    assert 0 < foggy['box AP drop'] < 100 and 0 < foggy['mIoU drop'] < 100
