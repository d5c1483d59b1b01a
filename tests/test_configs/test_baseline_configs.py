"""The baseline configs (configs/baselines/): load, build without weights,
one training step and one inference on CPU, 8 classes, our data and
evaluators.

The models are the configs' own; only the number of RoIs is cut (RPN
proposals 1000 -> 32, sampled RoIs 512 -> 32, detections 100 -> 10) and the
input is one 128x256 image, so the four big models run in seconds.
"""
import glob
import math
import os.path as osp

import pytest
import torch

from cbnet_lab.benchmark import (build_detector, has_mask_head,
                                 head_num_classes, make_batch, preprocess,
                                 train_step)
from cbnet_lab.config_edits import load_benchmark_cfg, read_config

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
CONFIGS = sorted(glob.glob(osp.join(ROOT, 'configs', 'baselines', '*.py')))
NAMES = [osp.basename(p)[:-3] for p in CONFIGS]
EXPECTED = {
    'faster-rcnn_x101-64x4d_fpn_1x_cityscapes': ('FasterRCNN', 'ResNeXt'),
    'yolox_s_8xb8-300e_cityscapes': ('YOLOX', 'CSPDarknet'),
    'mask-rcnn_pvt-v2-b2_fpn_1x_cityscapes':
    ('MaskRCNN', 'PyramidVisionTransformerV2'),
    'cascade-mask-rcnn_swin-s-p4-w7_fpn_1x_cityscapes':
    ('CascadeRCNN', 'SwinTransformer'),
}


def _few_rois(cfg):
    """Cut the RoI counts of two-stage models (test speed only)."""
    model = cfg.model
    if 'roi_head' not in model:
        model.test_cfg.max_per_img = 10
        return
    model.train_cfg.rpn_proposal.max_per_img = 32
    model.test_cfg.rpn.max_per_img = 32
    model.test_cfg.rcnn.max_per_img = 10
    rcnn = model.train_cfg.rcnn
    for stage in rcnn if isinstance(rcnn, list) else [rcnn]:
        stage.sampler.num = 32


def test_all_baselines_present():
    assert sorted(NAMES) == sorted(EXPECTED)


@pytest.mark.parametrize('path', CONFIGS, ids=NAMES)
def test_baseline_config_data_and_evaluation(path):
    cfg = read_config(path)
    name = osp.basename(path)[:-3]
    assert cfg.custom_imports == dict(
        imports=['cbnet_mmdet'], allow_failed_imports=False)
    assert cfg.model.type == EXPECTED[name][0]
    assert cfg.model.backbone.type == EXPECTED[name][1]
    assert cfg.data_root == 'data/cityscapes/'
    # the training set is wrapped (RepeatDataset / MultiImageMixDataset)
    train = cfg.train_dataloader.dataset.dataset
    for ds in (train, cfg.val_dataloader.dataset, cfg.test_dataloader.dataset):
        assert ds.type == 'CBNetCityscapesDataset'
        assert ds.data_root == 'data/cityscapes/'
    # training names the checking loader; testing MMCV's (DetInferencer
    # looks for that name) through the checking file backend
    loaders = [train.pipeline[0], cfg.val_dataloader.dataset.pipeline[0]]
    assert [t.type for t in loaders] == ['CBNetLoadImageFromFile',
                                         'LoadImageFromFile']
    assert loaders[1].backend_args == dict(backend='cbnet_image')
    evaluators = cfg.val_evaluator
    if isinstance(evaluators, dict):
        evaluators = [evaluators]
    types = [e.type for e in evaluators]
    masks = 'mask' in name
    assert types == (['CocoMetric', 'CBNetInstanceMIoUMetric',
                      'CBNetCityScapesMetric'] if masks else ['CocoMetric'])
    assert evaluators[0].metric in ((['bbox', 'segm'], ) if masks else
                                    ('bbox', ['bbox']))
    for e in evaluators[:2]:  # the official metric reads gtFine
        assert e.ann_file == ('data/cityscapes/annotations/'
                              'instancesonly_filtered_gtFine_val.json')


def test_baseline_data_pipelines_on_tiny_dataset(cityscapes_like_root):
    """Our dataset type and loader through each config's own pipelines."""
    from mmdet.registry import DATASETS
    from mmdet.utils import register_all_modules

    import cbnet_mmdet  # noqa: F401
    register_all_modules()
    for path in CONFIGS:
        cfg = read_config(path)
        for split, loader in (('train', cfg.train_dataloader),
                              ('val', cfg.val_dataloader)):
            ds_cfg = loader.dataset
            inner = ds_cfg.dataset if split == 'train' else ds_cfg
            inner.data_root = cityscapes_like_root
            dataset = DATASETS.build(ds_cfg)
            assert len(dataset.metainfo['classes']) == 8, path
            sample = dataset[0]
            assert sample['inputs'].shape[0] == 3, (path, split)
            if split == 'val':
                # full resolution: the generated 128x256 image upscaled to
                # Cityscapes' 1024x2048 (YOLOX: 512x1024 padded to square)
                assert max(sample['inputs'].shape[1:]) == (
                    1024 if 'yolox' in path else 2048), path


@pytest.mark.slow
@pytest.mark.parametrize('path', CONFIGS, ids=NAMES)
def test_baseline_builds_trains_and_predicts(path):
    torch.manual_seed(0)
    cfg = load_benchmark_cfg(path)
    assert cfg.load_from is None
    _few_rois(cfg)
    model = build_detector(cfg)
    # every head predicts the 8 Cityscapes classes (the RPN: 1 objectness)
    classes = head_num_classes(model)
    assert classes and set(classes) - {1} == {8}
    with_mask = has_mask_head(model)
    assert with_mask == ('mask' in osp.basename(path))
    batch = make_batch(1, (128, 256), num_items=3, with_mask=with_mask)

    model.train()
    loss = train_step(model, preprocess(model, batch, True))
    assert math.isfinite(loss.item()) and loss.item() > 0
    grads = [p.grad for p in model.parameters() if p.grad is not None]
    assert grads and any(g.abs().sum() > 0 for g in grads)

    model.eval()
    with torch.no_grad():
        results = model(**preprocess(model, batch, False), mode='predict')
    assert len(results) == 1
    pred = results[0].pred_instances
    assert len(pred) <= 10
    assert ((pred.labels >= 0) & (pred.labels < 8)).all()
    if with_mask:
        # masks at the original image size
        assert pred.masks.shape[1:] == (128, 256)
