"""tools/analysis_tools/browse_dataset.py on plain and paired data."""
import importlib.util
import os.path as osp

import mmcv
import numpy as np
from mmengine.config import Config

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')


def _tool():
    spec = importlib.util.spec_from_file_location(
        'browse_dataset',
        osp.join(ROOT, 'tools', 'analysis_tools', 'browse_dataset.py'))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _untouched(shape, boxes, margin=3, text=(60, 20)):
    """Pixels no box, mask or label of DetLocalVisualizer can reach: the
    boxes grown by ``margin`` and by a label's extent (w, h) below/right
    of the top-left corner."""
    keep = np.ones(shape[:2], bool)
    for x1, y1, x2, y2 in boxes:
        keep[max(0, int(y1) - margin):int(y2) + margin + 1,
             max(0, int(x1) - margin):int(x2) + margin + 1] = False
        keep[max(0, int(y1) - margin):int(y1) + text[1],
             max(0, int(x1) - margin):int(x1) + text[0]] = False
    return keep


def _write_cfg(cfg, tmp_path):
    path = str(tmp_path / 'cfg.py')
    cfg.dump(path)
    return path


def test_browse_plain_val(cityscapes_like_root, tmp_path):
    """Every val item is written; the ground truth is drawn on the images
    that have instances, the empty one is left as it is."""
    from mmdet.registry import DATASETS
    cfg = Config.fromfile(DEMO)
    cfg.val_dataloader.dataset.data_root = cityscapes_like_root + '/'
    out = tmp_path / 'vis'
    written = _tool().main([
        _write_cfg(cfg, tmp_path), '--split', 'val', '--output-dir',
        str(out), '--not-show'
    ])
    dataset = DATASETS.build(cfg.val_dataloader.dataset)
    assert len(written) == len(dataset) == 3
    counts = []
    for i, path in enumerate(written):
        info = dataset.get_data_info(i)
        assert osp.basename(path) == \
            f'{i:05d}_{osp.basename(info["img_path"])}'
        drawn = mmcv.imread(path)
        src = mmcv.imread(info['img_path'])
        assert drawn.shape == src.shape == (128, 256, 3)
        changed = np.abs(drawn.astype(int) - src).max() > 0
        counts.append(len(info['instances']))
        assert changed == (len(info['instances']) > 0), path
    assert 0 in counts and max(counts) > 0  # both cases seen


def test_browse_paired_shows_foggy_and_clear_with_the_same_flip(
        cityscapes_like_root, tmp_path):
    """A CBNet-DD item is drawn foggy | clear; outside the annotations the
    panels are exactly the flipped foggy and clear images."""
    cfg = Config.fromfile(DEMO)
    cfg.train_dataloader.dataset.dataset = dict(
        type='CBNetPairedFoggyDataset', beta=0.02,
        data_root=cityscapes_like_root + '/',
        ann_file='annotations/instancesonly_filtered_gtFine_train.json',
        data_prefix=dict(img='leftImg8bit/train/'),
        filter_cfg=dict(filter_empty_gt=True),
        pipeline=[
            dict(type='CBNetLoadPairedImageFromFile'),
            dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
            dict(type='RandomFlip', prob=1.0),  # always flipped
            dict(type='PackDetInputs')
        ])
    out = tmp_path / 'vis'
    tool = _tool()
    written = tool.main([
        _write_cfg(cfg, tmp_path), '--output-dir', str(out), '--not-show',
        '--max-items', '1'
    ])
    assert len(written) == 1
    drawn = mmcv.imread(written[0])
    assert drawn.shape == (128, 512, 3)
    from mmdet.registry import DATASETS
    item = DATASETS.build(cfg.train_dataloader.dataset)[0]
    info = item['data_samples']
    clear = mmcv.imread(info.img_path)[:, ::-1]
    from cbnet_mmdet.datasets.cityscapes_paths import foggy_path
    foggy = mmcv.imread(foggy_path(info.img_path, 0.02))[:, ::-1]
    assert np.abs(foggy.astype(int) - clear).mean() > 5  # really differ
    keep = _untouched(clear.shape,
                      info.gt_instances.bboxes.tensor.numpy())
    assert keep.mean() > 0.2
    np.testing.assert_array_equal(drawn[:, :256][keep], foggy[keep])
    np.testing.assert_array_equal(drawn[:, 256:][keep], clear[keep])
    assert np.abs(drawn[:, 256:].astype(int) - clear).max() > 0


def test_panels_reject_other_channel_counts():
    import pytest
    import torch
    with pytest.raises(ValueError, match='4 channels'):
        _tool().panels_of(torch.zeros(4, 8, 8, dtype=torch.uint8))
