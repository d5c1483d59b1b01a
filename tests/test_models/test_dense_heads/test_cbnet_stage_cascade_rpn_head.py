"""CBNetStageCascadeRPNHead against MMDet's StageCascadeRPNHead: same
parameters and outputs, MMDet's losses with ``normalize_by_num_pos=False``
or a sampler, and with the default the same losses rescaled from
``anchors / 200`` to the positives counted by MMDet's assigner."""
import copy
import math

import pytest
import torch
from mmcv.ops import DeformConv2d
from mmdet.models.dense_heads import StageCascadeRPNHead
from mmdet.registry import MODELS, TASK_UTILS
from mmdet.testing import demo_mm_inputs
from mmdet.utils import register_all_modules
from mmengine.config import ConfigDict
from mmengine.structures import InstanceData

import cbnet_mmdet  # noqa: F401  (registers the components)
from cbnet_mmdet.models.layers import CBNetDeformConv2d

register_all_modules()

STRIDES = (4, 8, 16, 32, 64)
CH = 8
IMG_HW = (64, 96)
#: Stage 2 of the paper's CRPN: offset-mode adaptive convolution, focal
#: objectness, GIoU regression (``CBNetCascadeRPNHead``'s second stage).
ASSIGNER = dict(type='MaxIoUAssigner', pos_iou_thr=0.5, neg_iou_thr=0.4,
                min_pos_iou=0.3, ignore_iof_thr=-1)
STAGE2 = dict(
    in_channels=CH,
    feat_channels=CH,
    anchor_generator=dict(type='AnchorGenerator', scales=[8], ratios=[1.0],
                          strides=list(STRIDES)),
    adapt_cfg=dict(type='offset'),
    bridged_feature=False,
    with_cls=True,
    reg_decoded_bbox=True,
    bbox_coder=dict(type='DeltaXYWHBBoxCoder', target_means=(0.0, ) * 4,
                    target_stds=(0.05, 0.05, 0.1, 0.1)),
    loss_cls=dict(type='FocalLoss', use_sigmoid=True, gamma=2.0, alpha=0.25,
                  loss_weight=1.0),
    loss_bbox=dict(type='GIoULoss', loss_weight=1.0),
    train_cfg=dict(assigner=ASSIGNER, allowed_border=-1, pos_weight=-1,
                   debug=False))
#: Stage 1: dilated adaptive convolution, IoU regression, no objectness.
STAGE1 = dict(
    STAGE2,
    adapt_cfg=dict(type='dilation', dilation=3),
    bridged_feature=True,
    with_cls=False,
    loss_cls=None,
    loss_bbox=dict(type='IoULoss', linear=True, loss_weight=10.0),
    train_cfg=dict(
        assigner=dict(type='RegionAssigner', center_ratio=0.2,
                      ignore_ratio=0.5),
        allowed_border=-1, pos_weight=-1, debug=False))


def build_pair(stage=STAGE2, **ours):
    """Ours (seeded init) and MMDet's stage head with the same weights."""
    cfg = ConfigDict(copy.deepcopy(stage))
    if cfg.get('loss_cls') is None:
        cfg.pop('loss_cls')
    torch.manual_seed(0)
    head = MODELS.build(dict(cfg, type='CBNetStageCascadeRPNHead', **ours))
    head.init_weights()
    with torch.no_grad():  # away from the zero-mean init: real positives
        for p in head.parameters():
            p.add_(0.05 * torch.randn_like(p))
    ref = StageCascadeRPNHead(**cfg)
    ref.load_state_dict(head.state_dict())  # strict: the same parameters
    return head, ref


def inputs(num_items=(3, 2), seed=0):
    g = torch.Generator().manual_seed(seed)
    feats = [
        torch.randn(len(num_items), CH, math.ceil(IMG_HW[0] / s),
                    math.ceil(IMG_HW[1] / s), generator=g) for s in STRIDES
    ]
    data = demo_mm_inputs(batch_size=len(num_items),
                          image_shapes=[(3, *IMG_HW)] * len(num_items),
                          num_items=list(num_items), num_classes=2)
    metas, gts = [], []
    for s in data['data_samples']:  # as an RPN sees them: one class
        s.gt_instances.labels = torch.zeros_like(s.gt_instances.labels)
        s.set_metainfo(dict(pad_shape=IMG_HW, batch_input_shape=IMG_HW))
        metas.append(s.metainfo)
        gts.append(s.gt_instances)
    return feats, metas, gts


def losses_of(head, feats, metas, gts):
    sizes = [f.shape[-2:] for f in feats]
    anchors, valid = head.get_anchors(sizes, metas, device='cpu')
    offsets = head.anchor_offset(anchors, head.anchor_strides, sizes) \
        if head.adapt_cfg['type'] == 'offset' else None
    _, cls_scores, bbox_preds = head(feats, offsets)
    return head.loss_by_feat(anchors, valid, cls_scores, bbox_preds, gts,
                             metas), anchors, valid


def summed(losses):
    return {k: sum(v) for k, v in losses.items()}


def positives_per_image(head, anchors, valid, gts):
    """Positive anchors per image, counted with MMDet's MaxIoUAssigner on
    the valid anchors (outside the head's loss code)."""
    assigner = TASK_UTILS.build(ASSIGNER)
    counts = []
    for img_anchors, img_valid, gt in zip(anchors, valid, gts):
        priors = torch.cat(img_anchors)[torch.cat(img_valid)]
        assigned = assigner.assign(InstanceData(priors=priors), gt)
        counts.append(int((assigned.gt_inds > 0).sum()))
    return counts


@pytest.mark.parametrize('deform_impl,conv_type', [
    ('auto', CBNetDeformConv2d), ('gather', CBNetDeformConv2d),
    ('mmcv', DeformConv2d)])
def test_same_parameters_and_outputs_as_mmdets_stage(deform_impl, conv_type):
    head, ref = build_pair(deform_impl=deform_impl)
    assert type(head.rpn_conv.conv) is conv_type
    assert head.state_dict().keys() == ref.state_dict().keys()
    feats, metas, _ = inputs()
    sizes = [f.shape[-2:] for f in feats]
    anchors, _ = head.get_anchors(sizes, metas, device='cpu')
    offsets = head.anchor_offset(anchors, head.anchor_strides, sizes)
    with torch.no_grad():
        got, expected = head(feats, offsets), ref(feats, offsets)
    for ours, theirs in zip(got[1] + got[2], expected[1] + expected[2]):
        torch.testing.assert_close(ours, theirs, rtol=1e-4, atol=1e-5)


def test_dilation_stage_keeps_mmdets_convolution():
    """Stage 1 (dilation mode) has no deformable convolution to swap."""
    head, ref = build_pair(STAGE1, deform_impl='gather')
    assert type(head.rpn_conv.conv) is torch.nn.Conv2d
    assert not head.with_cls and not hasattr(head, 'rpn_cls')
    feats, metas, gts = inputs()
    losses, _, _ = losses_of(head, feats, metas, gts)
    assert set(losses) == {'loss_rpn_reg'}


@pytest.mark.parametrize('stage', [STAGE1, STAGE2], ids=['stage1', 'stage2'])
def test_mmdets_factor_gives_mmdets_losses(stage):
    head, ref = build_pair(stage, normalize_by_num_pos=False,
                           deform_impl='mmcv')
    feats, metas, gts = inputs()
    got, _, _ = losses_of(head, feats, metas, gts)
    expected, _, _ = losses_of(ref, feats, metas, gts)
    assert set(got) == set(expected)
    for key in expected:
        for ours, theirs in zip(got[key], expected[key]):
            torch.testing.assert_close(ours, theirs, msg=key)


@pytest.mark.parametrize('num_items', [(3, 2), (0, 1), (0, 0)])
def test_losses_are_divided_by_the_positives(num_items):
    """Default: MMDet's losses times ``(anchors / 200) / positives`` (each
    image counting at least one positive, as MMDet's PseudoSampler)."""
    head, ref = build_pair(deform_impl='mmcv')
    feats, metas, gts = inputs(num_items)
    got, anchors, valid = losses_of(head, feats, metas, gts)
    expected, _, _ = losses_of(ref, feats, metas, gts)
    num_anchors = sum(a.shape[0] for img in anchors for a in img)
    positives = positives_per_image(head, anchors, valid, gts)
    assert (sum(positives) > 0) == (sum(num_items) > 0)
    avg_factor = sum(max(n, 1) for n in positives)
    scale = (num_anchors / 200.0) / avg_factor
    got, expected = summed(got), summed(expected)
    for key in ('loss_rpn_cls', 'loss_rpn_reg'):
        torch.testing.assert_close(got[key], expected[key] * scale, msg=key)
    if sum(num_items) == 0:  # no object: no regression loss at all
        assert got['loss_rpn_reg'].item() == 0


@pytest.mark.parametrize('normalize_by_num_pos', [True, False])
def test_a_sampler_keeps_its_own_factor(normalize_by_num_pos):
    """With a sampler in train_cfg both heads use its average factor."""
    stage = copy.deepcopy(STAGE2)
    stage['train_cfg']['sampler'] = dict(
        type='RandomSampler', num=64, pos_fraction=0.5, neg_pos_ub=-1,
        add_gt_as_proposals=False)
    head, ref = build_pair(stage, normalize_by_num_pos=normalize_by_num_pos,
                           deform_impl='mmcv')
    feats, metas, gts = inputs()
    torch.manual_seed(3)  # the sampler draws the same anchors
    got, _, _ = losses_of(head, feats, metas, gts)
    torch.manual_seed(3)
    expected, _, _ = losses_of(ref, feats, metas, gts)
    got, expected = summed(got), summed(expected)
    for key in expected:
        torch.testing.assert_close(got[key], expected[key], msg=key)


def test_bad_deform_impl():
    with pytest.raises(ValueError, match="'auto', 'gather' or 'mmcv'"):
        build_pair(deform_impl='cuda')
