"""Every shipped CBNet config builds, trains one step and predicts on CPU."""
import glob
import os.path as osp

import pytest
import torch
from mmdet.registry import MODELS
from mmdet.testing import demo_mm_inputs
from mmengine.config import Config
from mmengine.registry import init_default_scope

import cbnet_mmdet  # noqa: F401

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
CONFIGS = sorted(
    glob.glob(osp.join(ROOT, 'configs', 'cbnet*.py')) +
    glob.glob(osp.join(ROOT, 'configs', 'cbnet', '**', '*.py'),
              recursive=True) +
    glob.glob(osp.join(ROOT, 'configs', 'demo', '*.py')))
HEADLINE = osp.join(ROOT, 'configs', 'cbnet_cityscapes.py')


def _rel(path):
    return osp.relpath(path, ROOT)


def _for_cpu_test(model_cfg):
    """Pretrained init off (nothing to download); fewer RoIs per image.

    The architecture stays as configured; only run-time sampling sizes
    shrink so the big (B5, 7 NAS-FPN stacks) models step in seconds.
    """
    detector = model_cfg.get('detector', model_cfg)
    detector.backbone.init_cfg = None
    for stage in detector.train_cfg.rcnn:
        stage.sampler.num = 64
    detector.train_cfg.rpn_proposal.max_per_img = 100
    detector.test_cfg.rpn.max_per_img = 100
    return model_cfg


def test_configs_found():
    names = {_rel(c) for c in CONFIGS}
    assert 'configs/cbnet_cityscapes.py' in names
    for arch in ('b0', 'b1', 'b2', 'b3', 'b4', 'b5'):
        assert any(f'mit-{arch}' in n for n in names), arch
    assert sum('ablation' in n for n in names) == 4
    assert any('cbnet-dd' in n for n in names)


@pytest.mark.slow  # big backbones (B3-B5, 7 NAS-FPN stacks): 5-15 s each
@pytest.mark.parametrize('path', CONFIGS, ids=_rel)
def test_config_trains_one_step_and_predicts(path):
    cfg = Config.fromfile(path)
    init_default_scope(cfg.get('default_scope', 'mmdet'))
    model = MODELS.build(_for_cpu_test(cfg.model))
    channels = 6 if cfg.model.type == 'CBNetDistiller' else 3
    torch.manual_seed(0)
    packed = demo_mm_inputs(
        2, [[channels, 64, 128]] * 2, num_items=[3, 2], num_classes=8,
        with_mask=True)
    model.train()
    data = model.data_preprocessor(packed, True)
    losses = model(**data, mode='loss')
    loss, _ = model.parse_losses(losses)
    assert torch.isfinite(loss), {k: v for k, v in losses.items()}
    loss.backward()
    model.eval()
    packed = demo_mm_inputs(1, [[3, 64, 128]], num_classes=8)
    with torch.no_grad():
        data = model.data_preprocessor(packed, False)
        results = model(**data, mode='predict')
    pred = results[0].pred_instances
    assert tuple(pred.masks.shape[-2:]) == tuple(results[0].ori_shape)
    assert len(pred.bboxes) == len(pred.labels) == len(pred.scores)


def test_headline_config_is_the_papers_recipe():
    cfg = Config.fromfile(HEADLINE)
    m = cfg.model
    assert m.backbone.type == 'CBNetMiT' and m.backbone.arch == 'b5'
    assert m.backbone.act_cfg.type == 'Mish'
    assert m.backbone.pos_encoding == 'cspe'
    assert m.neck.type == 'CBNetNASFPN' and m.neck.out_channels == 256
    # CRPN: lambda_IoU = 10, lambda_obj = 1 (focal), lambda_GIoU = 10
    assert m.rpn_head.type == 'CBNetCascadeRPNHead'
    assert m.rpn_head.loss_iou.type == 'IoULoss'
    assert m.rpn_head.loss_iou.loss_weight == 10
    assert m.rpn_head.loss_obj.type == 'FocalLoss'
    assert m.rpn_head.loss_obj.loss_weight == 1
    assert m.rpn_head.loss_giou.type == 'GIoULoss'
    assert m.rpn_head.loss_giou.loss_weight == 10
    # k = 1000 proposals per image, training and testing
    assert m.train_cfg.rpn_proposal.max_per_img == 1000
    assert m.test_cfg.rpn.max_per_img == 1000
    # cascade: 3 stages at IoU 0.5 / 0.7 / 0.9, class-agnostic smooth-L1
    assert m.roi_head.type == 'CBNetCascadeRoIHead'
    assert m.roi_head.num_stages == 3
    assert [s.assigner.pos_iou_thr
            for s in m.train_cfg.rcnn] == [0.5, 0.7, 0.9]
    assert all(h.reg_class_agnostic for h in m.roi_head.bbox_head)
    assert all(h.loss_bbox.type == 'SmoothL1Loss'
               for h in m.roi_head.bbox_head)
    assert all(h.num_classes == 8 for h in m.roi_head.bbox_head)
    # one boundary-aware mask head (last stage only), both loss parts on
    mask = m.roi_head.mask_head
    assert isinstance(mask, dict) and mask.type == 'CBNetBoundaryMaskHead'
    assert mask.loss_mask.type == 'CBNetBoundaryAwareLoss'
    assert mask.loss_mask.use_shape and mask.loss_mask.use_edge
    # schedule: 12 epochs, AdamW lr 6e-5 wd 0.01, warm-up then poly
    assert cfg.train_cfg.max_epochs == 12
    opt = cfg.optim_wrapper.optimizer
    assert (opt.type, opt.lr, opt.weight_decay) == ('AdamW', 6e-5, 0.01)
    assert opt.foreach  # batched update (speed only, same arithmetic)
    assert [s.type for s in cfg.param_scheduler] == ['LinearLR', 'PolyLR']
    assert cfg.param_scheduler[1].end == 12
    # 12 real epochs (no RepeatDataset x8), 8 classes, AP + mIoU
    assert cfg.train_dataloader.dataset.times == 1
    assert len(cfg.train_dataloader.dataset.dataset.get(
        'metainfo', {}).get('classes', range(8))) == 8
    metrics = {e.type for e in cfg.val_evaluator}
    assert metrics == {'CocoMetric', 'CBNetInstanceMIoUMetric'}
    assert cfg.custom_imports.imports == ['cbnet_mmdet']


def test_no_weight_decay_on_norms_and_cspe_tables():
    """SegFormer's recipe: AdamW decays weights, not norms or the CSPE
    position tables (the paramwise keys must match real parameter names)."""
    from mmengine.optim import build_optim_wrapper
    cfg = Config.fromfile(
        osp.join(ROOT, 'configs', 'cbnet',
                 'cbnet_mit-b0_nasfpn-crpn_8xb1-12e_cityscapes.py'))
    init_default_scope('mmdet')
    model = MODELS.build(_for_cpu_test(cfg.model))
    wrapper = build_optim_wrapper(model, cfg.optim_wrapper)
    decay = {}
    for group in wrapper.optimizer.param_groups:
        for p in group['params']:
            decay[id(p)] = group['weight_decay']
    names = dict(model.named_parameters())
    tables = [n for n in names if n.endswith('cspe.table')]
    assert len(tables) == 8  # one per MiT-B0 block: depths 2, 2, 2, 2
    for name in tables:
        assert decay[id(names[name])] == 0.0, name
    norm = 'backbone.layers.0.1.0.norm1.weight'
    assert decay[id(names[norm])] == 0.0
    conv = 'backbone.layers.0.0.projection.weight'
    assert decay[id(names[conv])] == cfg.optim_wrapper.optimizer.weight_decay


def test_ablation_rows_switch_the_loss_parts():
    rows = {
        'ce': (False, False, False),
        'shape': (True, False, False),
        'shape-edge': (True, True, True),
    }
    for row, (shape, edge, edge_head) in rows.items():
        cfg = Config.fromfile(
            osp.join(ROOT, 'configs', 'cbnet', 'ablation',
                     f'cbnet_mit-b5_ablation-{row}_foggy-cityscapes.py'))
        mask = cfg.model.roi_head.mask_head
        assert mask.loss_mask.use_shape is shape, row
        assert mask.loss_mask.use_edge is edge, row
        assert (mask.get('loss_edge', 'default') is not None) is edge_head
        assert cfg.val_dataloader.dataset.type == \
            'CBNetFoggyCityscapesDataset'
    kd = Config.fromfile(
        osp.join(ROOT, 'configs', 'cbnet', 'ablation',
                 'cbnet_mit-b5_ablation-shape-edge-kd_foggy-cityscapes.py'))
    assert kd.model.type == 'CBNetDistiller'
    assert [h.type for h in kd.custom_hooks] == ['CBNetTeacherEMAHook']
    assert kd.train_dataloader.dataset.dataset.type == \
        'CBNetPairedFoggyDataset'
