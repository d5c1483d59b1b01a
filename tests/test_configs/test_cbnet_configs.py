"""Every shipped CBNet config builds, trains one step and predicts on CPU."""
import glob
import os.path as osp

import pytest
import torch
from mmdet.registry import MODELS
from mmdet.testing import demo_mm_inputs
from mmengine.registry import init_default_scope

from cbnet_lab.config_edits import read_config
import cbnet_mmdet  # noqa: F401

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
CONFIGS = sorted(
    glob.glob(osp.join(ROOT, 'configs', 'cbnet*.py')) +
    glob.glob(osp.join(ROOT, 'configs', 'cbnet', '**', '*.py'),
              recursive=True) +
    [p for p in glob.glob(osp.join(ROOT, 'configs', 'demo', '**', '*.py'),
                          recursive=True) if '_base_' not in p])
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
    rcnn = detector.train_cfg.get('rcnn')
    for stage in [rcnn] if isinstance(rcnn, dict) else rcnn or []:
        stage.sampler.num = 64
    if detector.train_cfg.get('rpn_proposal'):
        detector.train_cfg.rpn_proposal.max_per_img = 100
    detector.test_cfg.rpn.max_per_img = 100
    if detector.test_cfg.get('rcnn'):
        # an untrained head keeps 100 boxes, each through three mask
        # heads: 10 show the same path (12% of this file's time at 100)
        detector.test_cfg.rcnn.max_per_img = 10
    return model_cfg


def test_configs_found():
    names = {_rel(c) for c in CONFIGS}
    assert 'configs/cbnet_cityscapes.py' in names
    for arch in ('b0', 'b1', 'b2', 'b3', 'b4', 'b5'):
        assert any(f'mit-{arch}' in n for n in names), arch
    assert sum(n.startswith('configs/cbnet/ablation/') for n in names) == 4
    assert sum(n.startswith('configs/demo/ablation/') for n in names) == 4
    assert sum(n.startswith('configs/demo/rpn/') for n in names) == 3
    assert any('cbnet-dd' in n for n in names)


@pytest.mark.slow  # big backbones (B3-B5, 7 NAS-FPN stacks): 5-15 s each
@pytest.mark.parametrize('path', CONFIGS, ids=_rel)
def test_config_trains_one_step_and_predicts(path):
    cfg = read_config(path)
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
    if cfg.model.type != 'RPN':  # an RPN predicts proposals, no masks
        assert tuple(pred.masks.shape[-2:]) == tuple(results[0].ori_shape)
    assert len(pred.bboxes) == len(pred.labels) == len(pred.scores)


def test_headline_config_is_the_papers_recipe():
    cfg = read_config(HEADLINE)
    m = cfg.model
    assert m.backbone.type == 'CBNetMiT' and m.backbone.arch == 'b5'
    assert m.backbone.act_cfg.type == 'CBNetMish'
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
    # k = 1000 proposals per image in training; 300 kept at test time
    # (the paper's 1000 is one config value away)
    assert m.train_cfg.rpn_proposal.max_per_img == 1000
    assert m.test_cfg.rpn.max_per_img == 300
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
    # 12 real epochs (no RepeatDataset x8), 8 classes, COCO AP + mIoU +
    # the official Cityscapes AP
    assert cfg.train_dataloader.dataset.times == 1
    assert len(cfg.train_dataloader.dataset.dataset.get(
        'metainfo', {}).get('classes', range(8))) == 8
    metrics = {e.type for e in cfg.val_evaluator}
    assert metrics == {'CocoMetric', 'CBNetInstanceMIoUMetric',
                       'CBNetCityScapesMetric'}
    assert cfg.custom_imports.imports == ['cbnet_mmdet']


def test_no_weight_decay_on_norms_and_cspe_tables():
    """SegFormer's recipe: AdamW decays weights, not norms or the CSPE
    position tables (the paramwise keys must match real parameter names)."""
    from mmengine.optim import build_optim_wrapper
    cfg = read_config(
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


ABLATION = osp.join(ROOT, 'configs', 'cbnet', 'ablation')
ABLATION_ROWS = ('ce', 'shape', 'shape-edge', 'shape-edge-kd')


def ablation_cfg(row):
    return read_config(
        osp.join(ABLATION, f'cbnet_mit-b5_ablation-{row}_foggy-cityscapes.py'))


def test_ablation_rows_switch_the_loss_parts():
    rows = {'ce': (False, False), 'shape': (True, False),
            'shape-edge': (True, True)}
    for row, (shape, edge) in rows.items():
        cfg = ablation_cfg(row)
        mask = cfg.model.roi_head.mask_head
        assert mask.loss_mask.use_shape is shape, row
        assert mask.loss_mask.use_edge is edge, row
        assert mask.loss_edge is None, row  # no edge-map branch (eq. 9)
        assert cfg.val_dataloader.dataset.type == \
            'CBNetFoggyCityscapesDataset'
    kd = ablation_cfg('shape-edge-kd')
    assert kd.model.type == 'CBNetDistiller'
    assert [h.type for h in kd.custom_hooks] == ['CBNetTeacherEMAHook']
    assert kd.train_dataloader.dataset.dataset.type == \
        'CBNetPairedFoggyDataset'
    assert kd.model.detector.roi_head.mask_head == \
        ablation_cfg('shape-edge').model.roi_head.mask_head


def test_ablation_rows_share_one_training_pipeline():
    """Table 3's rows differ in the loss and the distillation only: the same
    transforms (the +KD row's 1024x512 crop included), the same filter, the
    same data; the +KD row loads the clear twin too (its loader)."""
    def train_set(row):
        ds = ablation_cfg(row).train_dataloader.dataset.dataset
        pipeline = [dict(t) for t in ds.pipeline]
        loader = pipeline.pop(0)['type']
        return loader, pipeline, ds.filter_cfg, ds.get('beta'), ds.ann_file

    ref_loader, *ref = train_set('shape-edge')
    for row in ABLATION_ROWS:
        loader, *rest = train_set(row)
        assert rest == ref, row
        assert loader == ('CBNetLoadPairedImageFromFile'
                          if row.endswith('kd') else ref_loader), row
    assert any(t['type'] == 'RandomCrop' for t in ref[0])


def test_paper_configs_give_from_scratch_parts_10x_lr():
    """Neck, RPN and RoI heads (from scratch) at 10x the fine-tuned
    backbone's lr (SegFormer's decode head multiplier); the demo, where the
    backbone is from scratch too, trains every part at one lr."""
    from mmengine.optim import build_optim_wrapper
    init_default_scope('mmdet')
    for path, mult in (
            (osp.join(ROOT, 'configs', 'cbnet',
                      'cbnet_mit-b0_nasfpn-crpn_8xb1-12e_cityscapes.py'), 10),
            (osp.join(ROOT, 'configs', 'demo',
                      'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'), 1)):
        cfg = read_config(path)
        model = MODELS.build(_for_cpu_test(cfg.model))
        wrapper = build_optim_wrapper(model, cfg.optim_wrapper)
        base = cfg.optim_wrapper.optimizer.lr
        lr = {}
        for group in wrapper.optimizer.param_groups:
            for p in group['params']:
                lr[id(p)] = group['lr']
        for name, p in model.named_parameters():
            part = name.split('.')[0]
            expected = base * (mult if part != 'backbone' else 1)
            assert lr[id(p)] == pytest.approx(expected), (path, name)


def test_paper_configs_sync_bn_in_the_neck():
    for name in ('cbnet_mit-b5_nasfpn-crpn_8xb1-12e_cityscapes.py',
                 'cbnet_mit-b0_nasfpn-crpn_8xb1-12e_cityscapes.py',
                 'cbnet_mit-b5_nasfpn-crpn_8xb1-12e_foggy-cityscapes.py'):
        cfg = read_config(osp.join(ROOT, 'configs', 'cbnet', name))
        assert cfg.model.neck.norm_cfg.type == 'SyncBN', name


# configs whose RoI head is ours (file names: every CBNet config but the
# RPN-only ones and MMDet's demo-size baselines)
CASCADE_CONFIGS = [
    p for p in CONFIGS if '/rpn/' not in p and not osp.basename(p).startswith(
        ('cascade-mask-rcnn', 'mask-rcnn'))
    # MMDet's CascadeRoIHead (a mask head per stage): the parts set's
    # CBNet rows and candidates that take it, and the revised CBNet
    and 'mask-per-stage' not in osp.basename(p)
    and not osp.basename(p).startswith('cbnet-revised')
]


@pytest.mark.parametrize('path', CASCADE_CONFIGS, ids=_rel)
def test_logged_mask_loss_is_the_configured_weight(path):
    """A mask loss pinned to 1 logs ``loss_weight``: the cascade's last
    stage weight (0.25) must not scale it (paper eq. 10)."""
    from unittest import mock

    from mmdet.testing import demo_mm_proposals
    cfg = read_config(path)
    detector = cfg.model.get('detector', cfg.model)
    assert detector.roi_head.type == 'CBNetCascadeRoIHead'
    init_default_scope('mmdet')
    head_cfg = detector.roi_head.copy()
    head_cfg.update(train_cfg=detector.train_cfg.rcnn,
                    test_cfg=detector.test_cfg.rcnn)
    for stage in head_cfg.train_cfg:
        stage.sampler.num = 32
    head = MODELS.build(head_cfg)
    channels = head_cfg.bbox_roi_extractor.out_channels
    torch.manual_seed(0)
    packed = demo_mm_inputs(1, [[3, 64, 64]], num_items=[3], num_classes=8,
                            with_mask=True)
    feats = tuple(torch.rand(1, channels, 64 // s, 64 // s)
                  for s in (4, 8, 16, 32, 64))
    proposals = demo_mm_proposals([(3, 64, 64)], 30)
    loss_fn = head.mask_head.loss_mask
    weight = detector.roi_head.mask_head.loss_mask.get('loss_weight', 1.0)

    def pinned(pred, *args, **kwargs):
        return pred.sum() * 0 + loss_fn.loss_weight

    with mock.patch.object(loss_fn, 'forward', side_effect=pinned):
        losses = head.loss(feats, proposals, packed['data_samples'])
    assert losses['s2.loss_mask'].item() == pytest.approx(weight)
