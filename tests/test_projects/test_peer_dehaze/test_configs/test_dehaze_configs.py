"""The peer baseline's configs (projects/peer_dehaze/configs): detector
configs shaped like the demo, checkpoints where the dehazer tool writes
them, each builds and steps on CPU."""
import glob
import os.path as osp

import pytest
import torch
from mmdet.registry import MODELS
from mmdet.testing import demo_mm_inputs
from mmengine.config import Config
from mmengine.registry import init_default_scope

import cbnet_dehaze  # noqa: F401

ROOT = osp.abspath(osp.join(osp.dirname(__file__), *['..'] * 4))
DEHAZE = osp.join(ROOT, 'projects', 'peer_dehaze', 'configs')
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
DEMO_DETECTORS = sorted(glob.glob(osp.join(DEHAZE, '*demo*.py')))
DETECTORS = sorted(
    set(glob.glob(osp.join(DEHAZE, '*.py'))) -
    set(glob.glob(osp.join(DEHAZE, 'dehazer_*.py'))))


def _name(path):
    return osp.basename(path)


def test_found():
    names = {_name(p) for p in DETECTORS}
    assert 'yolox_tiny_dehazer_1xb4-demo_cityscapes-like.py' in names
    assert 'cbnet_mit-b0_nasfpn_dehazer_1xb4-demo_cityscapes-like.py' in names
    assert len(DEMO_DETECTORS) == 2 and len(DETECTORS) == 4


@pytest.mark.parametrize('path', DETECTORS, ids=_name)
def test_checkpoint_is_where_the_tool_writes_it(path):
    """dehaze_checkpoint = work_dirs/dehaze/<dehazer config>/iter_<N>.pth"""
    cfg = Config.fromfile(path)
    ckpt = cfg.model.data_preprocessor.dehaze_checkpoint
    assert ckpt.startswith('work_dirs/dehaze/')
    dehazer_cfg = Config.fromfile(
        osp.join(DEHAZE, ckpt.split('/')[2] + '.py'))
    assert ckpt.endswith(f'/iter_{dehazer_cfg.train_cfg.max_iters}.pth')
    assert cfg.model.data_preprocessor.dehaze == \
        dehazer_cfg.model.dehazer.to_dict()


@pytest.mark.parametrize('path', DEMO_DETECTORS, ids=_name)
def test_demo_variants_share_the_demo_recipe(path):
    """What the comparison harness overrides is where the demo has it."""
    cfg, demo = Config.fromfile(path), Config.fromfile(DEMO)
    for key in ('data_root', 'train_cfg', 'param_scheduler', 'optim_wrapper',
                'train_dataloader', 'val_dataloader', 'randomness'):
        assert cfg.get(key) == demo.get(key), key
    types = [e['type'] for e in cfg.val_evaluator]
    assert types[0] == 'CocoMetric'
    assert cfg.val_evaluator[0].ann_file == demo.val_evaluator[0].ann_file


@pytest.mark.parametrize('path', DEMO_DETECTORS, ids=_name)
def test_demo_variant_trains_one_step(path):
    cfg = Config.fromfile(path)
    init_default_scope('mmdet')
    torch.manual_seed(0)
    # builds whether or not its dehazer checkpoint exists (it loads in
    # init_weights)
    model = MODELS.build(cfg.model)
    model.data_preprocessor.dehaze_checkpoint = None  # untrained
    model.init_weights()
    packed = demo_mm_inputs(2, [[3, 64, 128]] * 2, num_items=[3, 2],
                            num_classes=8, with_mask=True)
    data = model.data_preprocessor(packed, True)
    losses = model(**data, mode='loss')
    total = sum(v.sum() if isinstance(v, torch.Tensor) else sum(v)
                for k, v in losses.items() if 'loss' in k)
    assert torch.isfinite(total)
    total.backward()
    # frozen dehazer: no gradient reaches it, the detector gets one
    assert all(p.grad is None
               for p in model.data_preprocessor.dehazer.parameters())
    assert any(p.grad is not None for p in model.backbone.parameters())
