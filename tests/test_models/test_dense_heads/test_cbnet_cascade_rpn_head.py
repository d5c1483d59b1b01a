"""Tests of the paper's Cascade RPN head (``CBNetCascadeRPNHead``)."""
import math
import os.path as osp

import mmdet
import pytest
import torch
import torch.nn.functional as F
from mmdet.registry import MODELS
from mmdet.testing import demo_mm_inputs
from mmdet.utils import register_all_modules
from mmengine.config import Config, ConfigDict

import cbnet_mmdet  # noqa: F401  (registers the components)

STRIDES = (4, 8, 16, 32, 64)
CH = 8
KEYS = {'s0.loss_rpn_reg', 's1.loss_rpn_cls', 's1.loss_rpn_reg'}

register_all_modules()


#: The paper's proposal settings (k = 1000), as the base config's
#: train_cfg.rpn_proposal gives them to the head.
PAPER_PROPOSALS = dict(
    nms_pre=2000, max_per_img=1000, nms=dict(type='nms', iou_threshold=0.8),
    min_bbox_size=0)


def build_head(seed=0, **kwargs):
    torch.manual_seed(seed)
    cfg = dict(type='CBNetCascadeRPNHead', in_channels=CH, feat_channels=CH,
               test_cfg=PAPER_PROPOSALS)
    cfg.update(kwargs)
    head = MODELS.build(cfg)
    head.init_weights()
    return head


def pyramid(img_hw, batch, seed=0):
    """Random maps of a 4..64 pyramid: ceil(H / s) x ceil(W / s)."""
    g = torch.Generator().manual_seed(seed)
    return tuple(
        torch.randn(batch, CH, math.ceil(img_hw[0] / s),
                    math.ceil(img_hw[1] / s), generator=g) for s in STRIDES)


def samples(img_hw, num_items):
    """Data samples as an RPN sees them: one class, labels 0."""
    data = demo_mm_inputs(
        batch_size=len(num_items), image_shapes=(3, *img_hw),
        num_items=num_items, num_classes=2)
    for s in data['data_samples']:
        s.set_metainfo(dict(pad_shape=img_hw, batch_input_shape=img_hw))
        s.gt_instances.labels = torch.zeros_like(s.gt_instances.labels)
    return data['data_samples']


def total(losses, key):
    return sum(losses[key])


@pytest.mark.parametrize('num_items', [[0, 0], [1, 0], [3, 5]])
def test_loss_keys_and_finite(num_items):
    img_hw = (67, 45)
    head = build_head()
    losses = head.loss(pyramid(img_hw, 2), samples(img_hw, num_items))
    assert set(losses) == KEYS
    for key in KEYS:
        assert len(losses[key]) == len(STRIDES)
        assert torch.isfinite(total(losses, key))
    assert total(losses, 's1.loss_rpn_cls') > 0
    if sum(num_items) == 0:  # objectness only
        assert total(losses, 's0.loss_rpn_reg') == 0
        assert total(losses, 's1.loss_rpn_reg') == 0
    else:
        assert total(losses, 's0.loss_rpn_reg') > 0
        assert total(losses, 's1.loss_rpn_reg') > 0


def test_default_objective_is_the_papers():
    head = build_head()
    s1, s2 = head.stages
    assert type(s1.loss_bbox).__name__ == 'IoULoss'
    assert s1.loss_bbox.mode == 'linear' and s1.loss_bbox.loss_weight == 10
    assert not s1.with_cls and s1.adapt_cfg['type'] == 'dilation'
    assert type(s2.loss_cls).__name__ == 'FocalLoss'
    assert s2.loss_cls.use_sigmoid and s2.loss_cls.loss_weight == 1
    assert type(s2.loss_bbox).__name__ == 'GIoULoss'
    assert s2.loss_bbox.loss_weight == 10
    # the deformable (offset-mode) adaptive conv, mmcv's function
    assert type(s2.rpn_conv.conv).__name__ == 'CBNetDeformConv2d'
    assert s2.rpn_conv.adapt_type == 'offset'
    assert s1.reg_decoded_bbox and s2.reg_decoded_bbox
    assert s1.num_anchors == 1 and s2.anchor_strides == list(STRIDES)
    assert type(s1.assigner).__name__ == 'RegionAssigner'
    assert type(s2.assigner).__name__ == 'MaxIoUAssigner'
    # ignore band of a focal objective (RetinaNet's 0.5 / 0.4)
    assert (s2.assigner.pos_iou_thr, s2.assigner.neg_iou_thr) == (0.5, 0.4)
    assert s1.normalize_by_num_pos and s2.normalize_by_num_pos


@pytest.mark.parametrize('arg,keys', [
    ('loss_iou', {'s0.loss_rpn_reg'}),
    ('loss_obj', {'s1.loss_rpn_cls'}),
    ('loss_giou', {'s1.loss_rpn_reg'}),
])
def test_each_weight_scales_its_loss(arg, keys):
    img_hw = (64, 48)
    feats, data = pyramid(img_hw, 2), samples(img_hw, [2, 3])
    base = build_head()
    default = dict(
        loss_iou=dict(type='IoULoss', mode='linear', loss_weight=10.0),
        loss_obj=dict(type='FocalLoss', use_sigmoid=True, gamma=2.0,
                      alpha=0.25, loss_weight=1.0),
        loss_giou=dict(type='GIoULoss', loss_weight=10.0))[arg]
    doubled = build_head(**{arg: dict(default, loss_weight=2 *
                                      default['loss_weight'])})
    doubled.load_state_dict(base.state_dict())
    a, b = base.loss(feats, data), doubled.loss(feats, data)
    for key in KEYS:
        factor = 2.0 if key in keys else 1.0
        torch.testing.assert_close(total(b, key), factor * total(a, key))
    assert total(a, next(iter(keys))) > 0


def num_anchors(img_hw):
    """Anchors of one image on the 4..64 pyramid (one per location)."""
    return sum(
        math.ceil(img_hw[0] / s) * math.ceil(img_hw[1] / s) for s in STRIDES)


def negatives_only_focal(img_hw, p, batch, normalize_by_num_pos):
    """Closed form of the objectness loss when every anchor is negative.

    The focal term of one negative is (1 - alpha) p**2 (-log(1 - p)); the
    sum over the batch's anchors is divided by the number of positives (at
    least 1 per image) or, MMDet's way, by anchors / 200.
    """
    per_anchor = 0.75 * p**2 * -torch.log1p(-p)
    anchors = batch * num_anchors(img_hw)
    divisor = batch if normalize_by_num_pos else anchors / 200
    return anchors * per_anchor / divisor


@pytest.mark.parametrize('normalize_by_num_pos', [True, False])
def test_focal_objectness_closed_form_without_gt(normalize_by_num_pos):
    """No ground truth: every anchor is a negative, with a constant logit."""
    img_hw = (40, 56)
    head = build_head(normalize_by_num_pos=normalize_by_num_pos)
    cls = head.stages[1].rpn_cls
    torch.nn.init.zeros_(cls.weight)
    torch.nn.init.constant_(cls.bias, 0.3)
    losses = head.loss(pyramid(img_hw, 2), samples(img_hw, [0, 0]))
    expected = negatives_only_focal(
        img_hw, torch.sigmoid(torch.tensor(0.3)), 2, normalize_by_num_pos)
    torch.testing.assert_close(total(losses, 's1.loss_rpn_cls'), expected)


def padded_pyramid(feats, img_hw):
    """``feats`` zero-padded (right and bottom) to the pyramid of img_hw."""
    out = []
    for f, s in zip(feats, STRIDES):
        h, w = math.ceil(img_hw[0] / s), math.ceil(img_hw[1] / s)
        out.append(F.pad(f, (0, w - f.shape[-1], 0, h - f.shape[-2])))
    return tuple(out)


def fixed_objects(img_hw):
    """Three boxes inside the top-left 96x96 pixels, on an img_hw image."""
    data = samples(img_hw, [3])
    data[0].gt_instances.bboxes = torch.tensor(
        [[8., 10., 40., 50.], [30., 20., 90., 60.], [50., 52., 80., 92.]])
    return data


@pytest.mark.parametrize('normalize_by_num_pos', [True, False])
def test_loss_per_positive_independent_of_image_size(normalize_by_num_pos):
    """The same objects and features in an image twice the size.

    Zero-padding the features keeps every original location's output (the
    convolutions pad with zeros too), so the positives and their
    predictions are the same; only negatives are added. Averaged per
    positive, the regression losses are unchanged and the objectness grows
    only by the new easy negatives' focal terms (tiny at the prior p=0.01);
    MMDet's anchors / 200 factor divides them all by about 4x more.
    """
    small, large = (128, 128), (256, 256)
    head = build_head(normalize_by_num_pos=normalize_by_num_pos)
    feats = pyramid(small, 1)
    with torch.no_grad():
        a = head.loss(feats, fixed_objects(small))
        b = head.loss(padded_pyramid(feats, large), fixed_objects(large))
    assert total(a, 's0.loss_rpn_reg') > 0 and total(a, 's1.loss_rpn_reg') > 0
    if normalize_by_num_pos:
        for key in ('s0.loss_rpn_reg', 's1.loss_rpn_reg'):
            torch.testing.assert_close(total(b, key), total(a, key))
        torch.testing.assert_close(
            total(b, 's1.loss_rpn_cls'), total(a, 's1.loss_rpn_cls'),
            rtol=0.02, atol=0)
    else:
        ratio = total(a, 's0.loss_rpn_reg') / total(b, 's0.loss_rpn_reg')
        expected = num_anchors(large) / num_anchors(small)
        assert ratio.item() == pytest.approx(expected, rel=1e-4)


def test_iou_loss_is_a_mean_over_positives():
    """Stage 1 logs lambda_IoU times the mean (1 - IoU), at most 10."""
    img_hw = (128, 128)
    head = build_head()
    losses = head.loss(pyramid(img_hw, 2), samples(img_hw, [3, 4]))
    assert 0 < total(losses, 's0.loss_rpn_reg').item() <= 10.0
    assert 0 < total(losses, 's1.loss_rpn_reg').item() <= 20.0  # 1-GIoU<=2


@pytest.mark.parametrize('k', [1000, 25])
def test_proposals_capped_at_k_and_inside_image(k):
    img_hw = (256, 200)  # 5,000+ anchors, more than k
    head = build_head(test_cfg=dict(
        nms_pre=2000, max_per_img=k, nms=dict(type='nms', iou_threshold=0.8),
        min_bbox_size=0))
    with torch.no_grad():
        results = head.predict(pyramid(img_hw, 2), samples(img_hw, [1, 1]))
    assert len(results) == 2
    for res in results:
        assert 0 < len(res) <= k
        b = res.bboxes
        assert (b[:, 0] >= 0).all() and (b[:, 1] >= 0).all()
        assert (b[:, 2] <= img_hw[1]).all() and (b[:, 3] <= img_hw[0]).all()
        assert (b[:, 2] >= b[:, 0]).all() and (b[:, 3] >= b[:, 1]).all()
        assert ((res.scores >= 0) & (res.scores <= 1)).all()
    if k == 25:
        assert all(len(res) == k for res in results)


def test_loss_and_predict_uses_proposal_cfg():
    img_hw = (96, 64)
    head = build_head()
    proposal_cfg = Config(dict(
        nms_pre=500, max_per_img=7, nms=dict(type='nms', iou_threshold=0.7),
        min_bbox_size=0))
    losses, results = head.loss_and_predict(
        pyramid(img_hw, 2), samples(img_hw, [1, 2]), proposal_cfg)
    assert set(losses) == KEYS
    assert [len(r) for r in results] == [7, 7]


def test_gradients_reach_adaptive_conv_offsets():
    img_hw = (64, 64)
    head = build_head()
    feats, data = pyramid(img_hw, 2), samples(img_hw, [2, 1])
    # whole head: both adaptive convolutions receive gradients
    losses = head.loss(feats, data)
    sum(sum(v) for v in losses.values()).backward()
    for stage in head.stages:
        grad = stage.rpn_conv.conv.weight.grad
        assert grad is not None and grad.abs().sum() > 0
    # stage 2: the anchor-shaped offsets of the deformable conv get gradients
    s1, s2 = head.stages
    metas = [d.metainfo for d in data]
    sizes = [f.shape[-2:] for f in feats]
    anchors, _ = s1.get_anchors(sizes, metas, device='cpu')
    bridged, _, reg = s1(list(feats))
    anchors = s1.refine_bboxes(anchors, reg, metas)
    offsets = [
        o.detach().requires_grad_()
        for o in s2.anchor_offset(anchors, s2.anchor_strides, sizes)
    ]
    _, cls, reg = s2(bridged, offsets)
    (sum(c.sum() for c in cls) + sum(r.sum() for r in reg)).backward()
    for o in offsets:
        assert o.grad is not None and torch.isfinite(o.grad).all()
        assert o.grad.abs().sum() > 0


def test_offset_adaption_matches_dilated_conv():
    """Independent reference: a square anchor of side 8 x stride centred on
    its location lays the 3x3 grid at +-4 cells, i.e. a dilation-4 conv."""
    img_hw = (48, 40)
    head = build_head()
    s2 = head.stages[1]
    feats = pyramid(img_hw, 1)
    sizes = [f.shape[-2:] for f in feats]
    metas = [d.metainfo for d in samples(img_hw, [0])]
    anchors, _ = s2.get_anchors(sizes, metas, device='cpu')
    offsets = s2.anchor_offset(anchors, s2.anchor_strides, sizes)
    weight = s2.rpn_conv.conv.weight
    with torch.no_grad():
        for x, off in zip(feats, offsets):
            out = s2.rpn_conv(x, off)
            ref = F.conv2d(x, weight, padding=4, dilation=4)
            torch.testing.assert_close(out, ref, atol=1e-5, rtol=1e-4)


@pytest.mark.parametrize('train_cfg,match', [
    (dict(assigner=dict(type='MaxIoUAssigner')), 'single dict'),
    ([dict()], 'one dict per stage'),
])
def test_bad_train_cfg(train_cfg, match):
    with pytest.raises(ValueError, match=match):
        build_head(train_cfg=train_cfg)


def test_proposal_settings_come_from_the_config_alone():
    """No proposal defaults in code: a head without test_cfg trains, and
    proposing then asks for the settings instead of inventing a k."""
    img_hw = (67, 45)
    head = build_head(test_cfg=None)
    assert head.test_cfg is None
    x, data = pyramid(img_hw, 2), samples(img_hw, [2, 1])
    assert set(head.loss(x, data)) == KEYS
    for propose in (lambda: head.predict(x, data),
                    lambda: head.loss_and_predict(x, data)):
        with pytest.raises(ValueError, match='no proposal settings'):
            propose()
    _, proposals = head.loss_and_predict(
        x, data, proposal_cfg=ConfigDict(PAPER_PROPOSALS, max_per_img=5))
    assert all(len(p) <= 5 for p in proposals)


def test_bad_objectness_loss():
    with pytest.raises(ValueError, match='use_sigmoid'):
        build_head(loss_obj=dict(type='CrossEntropyLoss'))


def faster_rcnn_cfg(neck, crpn):
    """MMDet's stock Faster R-CNN, shrunk (ResNet-18 at 1/8 width), with the
    given neck and either our head or the stock ``RPNHead``."""
    cfg = Config.fromfile(
        osp.join(osp.dirname(mmdet.__file__),
                 '.mim/configs/_base_/models/faster-rcnn_r50_fpn.py')).model
    cfg.backbone.update(depth=18, base_channels=8, init_cfg=None)
    cfg.neck = neck
    if crpn:
        cfg.rpn_head = dict(type='CBNetCascadeRPNHead', in_channels=CH,
                            feat_channels=CH)
        cfg.train_cfg.rpn = None  # the head's per-stage defaults
    else:
        cfg.rpn_head.update(in_channels=CH, feat_channels=CH)
    cfg.roi_head.bbox_roi_extractor.out_channels = CH
    cfg.roi_head.bbox_head.update(in_channels=CH, fc_out_channels=16,
                                  num_classes=8)
    cfg.train_cfg.rcnn.sampler.num = 32
    return cfg


FPN = dict(type='FPN', in_channels=[8, 16, 32, 64], out_channels=CH,
           num_outs=5)
NAS = dict(type='CBNetNASFPN', in_channels=[8, 16, 32, 64], out_channels=CH,
           stack_times=1)


@pytest.mark.parametrize('neck,crpn', [(FPN, True), (NAS, False),
                                       (NAS, True)],
                         ids=['FPN+CRPN', 'NASFPN+RPNHead', 'NASFPN+CRPN'])
def test_drop_in_faster_rcnn(neck, crpn):
    """Neck and head each replace their stock counterpart in Faster R-CNN:
    loss (with proposals from ``loss_and_predict``) and predict run."""
    torch.manual_seed(0)
    model = MODELS.build(faster_rcnn_cfg(neck, crpn))
    data = demo_mm_inputs(2, (3, 97, 75), num_items=[3, 0], num_classes=8)
    losses = model(**model.data_preprocessor(data, True), mode='loss')
    if crpn:
        assert KEYS <= set(losses)
    assert {'loss_cls', 'loss_bbox'} <= set(losses)
    loss, _ = model.parse_losses(losses)
    assert torch.isfinite(loss)
    loss.backward()
    model.eval()
    with torch.no_grad():
        preds = model(**model.data_preprocessor(data, False), mode='predict')
    assert len(preds) == 2
    for p in preds:
        assert p.pred_instances.bboxes.shape[1] == 4


def test_documented_config_delta_builds():
    """The docstring's two-line change to a stock Faster R-CNN config."""
    cfg = Config.fromstring(
        "_base_ = 'mmdet::faster_rcnn/faster-rcnn_r50_fpn_1x_coco.py'\n"
        'model = dict(\n'
        '    backbone=dict(depth=18, base_channels=8, init_cfg=None),\n'
        '    neck=dict(in_channels=[8, 16, 32, 64]),\n'
        "    rpn_head=dict(_delete_=True, type='CBNetCascadeRPNHead'),\n"
        '    train_cfg=dict(rpn=None))\n', file_format='.py')
    model = MODELS.build(cfg.model)
    head = model.rpn_head
    assert type(head).__name__ == 'CBNetCascadeRPNHead'
    assert [type(s.assigner).__name__ for s in head.stages] == [
        'RegionAssigner', 'MaxIoUAssigner'
    ]
    assert model.train_cfg.rpn_proposal.max_per_img == 1000
    assert head.test_cfg.max_per_img == 1000


@pytest.mark.parametrize('prior', [0.01, 0.2])
def test_objectness_starts_at_focal_prior(prior):
    """After init_weights every anchor scores `obj_prior_prob`, so the focal
    objectness loss starts small instead of swamping the gradient."""
    head = build_head(obj_prior_prob=prior)
    head.init_weights()
    cls = head.stages[1].rpn_cls
    torch.testing.assert_close(
        torch.sigmoid(cls.bias), torch.full_like(cls.bias, prior))
    img_hw = (40, 56)
    losses = head.loss(pyramid(img_hw, 2), samples(img_hw, [0, 0]))
    # a zero-mean weight of std 0.01 on unit features barely moves p
    expected = negatives_only_focal(img_hw, torch.tensor(prior), 2, True)
    torch.testing.assert_close(
        total(losses, 's1.loss_rpn_cls'), expected, rtol=0.3, atol=1e-3)
