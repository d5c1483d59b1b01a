"""CBNetCascadeRoIHead: last-stage-only mask head, losses, inference."""
import copy
from unittest import mock

import numpy as np
import pytest
import torch
from mmengine.config import ConfigDict
from mmengine.structures import InstanceData
from mmdet.registry import MODELS
from mmdet.structures import DetDataSample
from mmdet.structures.bbox import bbox2roi
from mmdet.structures.mask import BitmapMasks
from mmdet.testing import demo_mm_inputs, demo_mm_proposals
from mmdet.utils import register_all_modules

import cbnet_mmdet  # noqa: F401  (registers the modules)

CH = 16  # feature channels of the tiny test models
NUM_CLASSES = 3
IOU_THRS = (0.5, 0.7, 0.9)


def bbox_head(cls_sigmoid=False):
    return dict(
        type='Shared2FCBBoxHead',
        in_channels=CH,
        fc_out_channels=32,
        roi_feat_size=7,
        num_classes=NUM_CLASSES,
        bbox_coder=dict(
            type='DeltaXYWHBBoxCoder',
            target_means=[0., 0., 0., 0.],
            target_stds=[0.1, 0.1, 0.2, 0.2]),
        reg_class_agnostic=True,
        # paper eq. (4) (per-class BCE) or MMDet's softmax CE
        loss_cls=dict(type='CBNetSigmoidCrossEntropyLoss')
        if cls_sigmoid else dict(type='CrossEntropyLoss', loss_weight=1.0),
        loss_bbox=dict(type='SmoothL1Loss', beta=1.0, loss_weight=1.0))


def roi_head_cfg(mask_head=None, cls_sigmoid=False, num_sample=64):
    if mask_head is None:
        mask_head = dict(
            type='CBNetBoundaryMaskHead',
            num_convs=1,
            in_channels=CH,
            conv_out_channels=CH,
            num_classes=NUM_CLASSES,
            loss_mask=dict(
                type='CBNetBoundaryAwareLoss', lambda_shape=1.,
                lambda_edge=1.))
    stage_train = [
        dict(
            assigner=dict(
                type='MaxIoUAssigner', pos_iou_thr=thr, neg_iou_thr=thr,
                min_pos_iou=thr, match_low_quality=False, ignore_iof_thr=-1),
            sampler=dict(
                type='RandomSampler', num=num_sample, pos_fraction=0.25,
                neg_pos_ub=-1, add_gt_as_proposals=True),
            mask_size=28,
            pos_weight=-1,
            debug=False) for thr in IOU_THRS
    ]
    return ConfigDict(
        type='CBNetCascadeRoIHead',
        num_stages=3,
        stage_loss_weights=[1, 0.5, 0.25],
        bbox_roi_extractor=dict(
            type='SingleRoIExtractor',
            roi_layer=dict(type='RoIAlign', output_size=7, sampling_ratio=0),
            out_channels=CH,
            featmap_strides=[4, 8, 16, 32]),
        bbox_head=[bbox_head(cls_sigmoid) for _ in range(3)],
        mask_roi_extractor=dict(
            type='SingleRoIExtractor',
            roi_layer=dict(type='RoIAlign', output_size=14, sampling_ratio=0),
            out_channels=CH,
            featmap_strides=[4, 8, 16, 32]),
        mask_head=mask_head,
        train_cfg=stage_train,
        test_cfg=dict(
            score_thr=0.0,
            nms=dict(type='nms', iou_threshold=0.5),
            max_per_img=20,
            mask_thr_binary=0.5))


def unit_inputs(num_items=(3, 2), size=64):
    shapes = [(3, size, size)] * len(num_items)
    packed = demo_mm_inputs(
        batch_size=len(num_items), image_shapes=shapes,
        num_items=list(num_items), num_classes=NUM_CLASSES, with_mask=True)
    feats = tuple(
        torch.rand(len(num_items), CH, size // s, size // s)
        for s in (4, 8, 16, 32))
    proposals = demo_mm_proposals(shapes, 40)
    return feats, proposals, packed['data_samples']


def count_calls(module):
    return mock.patch.object(
        module, 'forward', side_effect=module.forward, autospec=False)


def test_init_from_config():
    head = MODELS.build(roi_head_cfg())
    assert [a.pos_iou_thr for a in head.bbox_assigner] == list(IOU_THRS)
    assert all(h.reg_class_agnostic for h in head.bbox_head)
    assert type(head.mask_head).__name__ == 'CBNetBoundaryMaskHead'
    assert not isinstance(head.mask_head, torch.nn.ModuleList)
    with pytest.raises(TypeError, match='single config'):
        MODELS.build(roi_head_cfg(mask_head=[roi_head_cfg().mask_head] * 3))


def test_loss_only_last_stage_has_mask():
    torch.manual_seed(0)
    head = MODELS.build(roi_head_cfg())
    feats, proposals, samples = unit_inputs()
    with count_calls(head.mask_head) as spy:
        losses = head.loss(feats, proposals, samples)
    assert spy.call_count == 1
    for stage in range(3):
        assert f's{stage}.loss_cls' in losses
        assert f's{stage}.loss_bbox' in losses
    mask_keys = sorted(k for k in losses if 'mask' in k or 'edge' in k)
    assert mask_keys == ['s2.loss_edge', 's2.loss_mask']
    total = sum(v for k, v in losses.items() if 'loss' in k)
    assert torch.isfinite(total)
    total.backward()
    assert head.mask_head.conv_edge.weight.grad.abs().sum() > 0
    assert head.mask_head.conv_logits.weight.grad.abs().sum() > 0


def test_stage_weight_does_not_scale_mask_loss():
    """Paper eq. (10): L_bound enters the total at its own weight.

    MMDet's cascade loop multiplies stage 2's losses by
    ``stage_loss_weights[2]``; the mask losses must not be (the box losses
    still are).
    """
    head = MODELS.build(roi_head_cfg())
    feats, proposals, samples = unit_inputs()
    torch.manual_seed(1)
    base = head.loss(feats, copy.deepcopy(proposals), samples)
    head.stage_loss_weights = [1, 0.5, 1.0]
    torch.manual_seed(1)
    scaled = head.loss(feats, copy.deepcopy(proposals), samples)
    torch.testing.assert_close(scaled['s2.loss_mask'], base['s2.loss_mask'])
    torch.testing.assert_close(scaled['s2.loss_edge'], base['s2.loss_edge'])
    torch.testing.assert_close(scaled['s2.loss_bbox'],
                               4 * base['s2.loss_bbox'])


def test_box_losses_are_mmdets_cascade_loop():
    """MMDet's cascade loop gives MMDet's ``CascadeRoIHead.loss`` box
    losses exactly (same weights, same sampling seed), and the mask losses
    are the mask head's alone; the head keeps no state between calls."""
    ours = MODELS.build(roi_head_cfg())
    cfg = roi_head_cfg()
    cfg.type = 'CascadeRoIHead'
    cfg.pop('mask_head'), cfg.pop('mask_roi_extractor', None)
    stock = MODELS.build(cfg)
    missing, unexpected = stock.load_state_dict(ours.state_dict(),
                                                strict=False)
    assert not missing and all(k.startswith('mask_') for k in unexpected)
    feats, proposals, samples = unit_inputs()
    torch.manual_seed(1)
    got = ours.loss(feats, copy.deepcopy(proposals), samples)
    torch.manual_seed(1)
    ref = stock.loss(feats, copy.deepcopy(proposals), samples)
    assert set(got) - set(ref) == {'s2.loss_mask', 's2.loss_edge'}
    for key, value in ref.items():
        torch.testing.assert_close(got[key], value)
    assert vars(ours).keys() == vars(MODELS.build(roi_head_cfg())).keys()


def test_mask_loss_of_a_stage_without_mask_head_is_empty():
    """MMDet's loop calls ``mask_loss`` on every stage: before the last
    nothing runs and no loss is added; a stage the head does not have, or
    a last stage weighted 0 (the mask losses could not be unscaled), is an
    error."""
    head = MODELS.build(roi_head_cfg())
    feats, _, samples = unit_inputs()
    gts = [s.gt_instances for s in samples]
    for stage in (0, 1, -3, -2):
        with count_calls(head.mask_head) as spy:
            assert head.mask_loss(stage, feats, [], gts) == \
                dict(loss_mask=dict())
        assert spy.call_count == 0
    for stage in (3, -4):
        with pytest.raises(ValueError, match='stages 0..2'):
            head.mask_loss(stage, feats, [], gts)
    head.stage_loss_weights = [1, 0.5, 0]
    with pytest.raises(ValueError, match=r'stage_loss_weights\[-1\] must '
                       r'be > 0'):
        head.mask_loss(2, feats, [], gts)


def test_logged_mask_loss_is_the_configured_weight():
    """A mask loss pinned to 1 logs exactly ``loss_weight`` (not 0.25)."""
    cfg = roi_head_cfg()
    cfg.mask_head.loss_mask.loss_weight = 3.0
    head = MODELS.build(cfg)
    feats, proposals, samples = unit_inputs()
    loss_fn = head.mask_head.loss_mask

    def pinned(pred, *args, **kwargs):
        return pred.sum() * 0 + loss_fn.loss_weight

    with mock.patch.object(loss_fn, 'forward', side_effect=pinned):
        losses = head.loss(feats, proposals, samples)
    assert losses['s2.loss_mask'].item() == pytest.approx(3.0)


def test_mask_loss_matches_mask_head_on_last_stage_samples():
    """``s2.loss_mask`` = the mask head's own loss on stage 2's positives."""
    head = MODELS.build(roi_head_cfg())
    feats, proposals, samples = unit_inputs()
    records = []
    original = head.mask_loss

    def recording(stage, x, sampling_results, gt):
        out = original(stage, x, sampling_results, gt)
        records.append((stage, sampling_results, gt, out))
        return out

    with mock.patch.object(head, 'mask_loss', side_effect=recording):
        losses = head.loss(feats, proposals, samples)
    stage, sampling_results, gt, out = records[-1]
    assert stage == 2
    reference = head.mask_head.loss_and_target(
        mask_preds=out['mask_preds'], sampling_results=sampling_results,
        batch_gt_instances=gt, rcnn_train_cfg=head.train_cfg[2],
        edge_preds=out['edge_preds'])['loss_mask']
    torch.testing.assert_close(losses['s2.loss_mask'],
                               reference['loss_mask'])
    torch.testing.assert_close(losses['s2.loss_edge'],
                               reference['loss_edge'])


def test_loss_without_gt_is_finite():
    head = MODELS.build(roi_head_cfg())
    feats, proposals, samples = unit_inputs()
    for sample in samples:
        sample.gt_instances = sample.gt_instances[:0]
    losses = head.loss(feats, proposals, samples)
    assert losses['s2.loss_mask'].item() == 0
    for value in losses.values():
        assert torch.isfinite(value).all()


def test_mask_forward_contract():
    head = MODELS.build(roi_head_cfg())
    feats, _, _ = unit_inputs()
    rois = torch.tensor([[0., 2., 2., 30., 40.], [1., 10., 5., 60., 60.]])
    for stage in (2, -1):
        out = head._mask_forward(stage, feats, rois)
        assert out['mask_preds'].shape == (2, NUM_CLASSES, 28, 28)
        assert out['edge_preds'].shape == (2, 1, 28, 28)
    with pytest.raises(ValueError, match='last stage only'):
        head._mask_forward(0, feats, rois)


def test_predict_masks_from_last_stage_once():
    torch.manual_seed(0)
    head = MODELS.build(roi_head_cfg()).eval()
    feats, proposals, samples = unit_inputs()
    with torch.no_grad(), count_calls(head.mask_head) as spy:
        results = head.predict(feats, proposals, samples, rescale=True)
    assert spy.call_count == 1
    assert len(results) == 2
    for res in results:
        assert len(res) > 0
        assert res.masks.shape[1:] == (64, 64)
        assert res.masks.dtype == torch.bool
    # tensor mode: last-stage mask probabilities only
    with torch.no_grad(), count_calls(head.mask_head) as spy:
        outs = head.forward(feats, proposals, samples)
    assert spy.call_count == 1 and len(outs) == 3
    assert outs[2][0].shape == (40, NUM_CLASSES, 28, 28)
    assert 0 <= outs[2][0].min() and outs[2][0].max() <= 1


def test_predict_without_detections():
    head = MODELS.build(roi_head_cfg()).eval()
    feats, proposals, samples = unit_inputs()
    empty = [InstanceData(bboxes=torch.zeros(0, 4)) for _ in proposals]
    with torch.no_grad():
        results = head.predict(feats, empty, samples)
    assert all(len(r) == 0 and r.masks.shape[0] == 0 for r in results)


def test_plain_fcn_mask_head_and_sigmoid_cls():
    """Works with MMDet's FCNMaskHead (no edge) and eq. (4)'s BCE."""
    mask_head = dict(
        type='FCNMaskHead', num_convs=1, in_channels=CH,
        conv_out_channels=CH, num_classes=NUM_CLASSES)
    head = MODELS.build(roi_head_cfg(mask_head=mask_head, cls_sigmoid=True))
    feats, proposals, samples = unit_inputs()
    losses = head.loss(feats, copy.deepcopy(proposals), samples)
    assert 's2.loss_mask' in losses and 's2.loss_edge' not in losses
    assert all(torch.isfinite(v).all() for v in losses.values())
    assert all(h.fc_cls.out_features == NUM_CLASSES for h in head.bbox_head)
    head.eval()
    with torch.no_grad():
        results = head.predict(feats, proposals, samples, rescale=True)
    assert results[0].masks.shape[1:] == (64, 64)
    assert all(((r.scores >= 0) & (r.scores <= 1)).all() for r in results)


# --------------------------------------------------------------------------
# A tiny end-to-end detector trained for a few iterations
# --------------------------------------------------------------------------
def tiny_detector_cfg():
    rpn_train = dict(
        assigner=dict(
            type='MaxIoUAssigner', pos_iou_thr=0.7, neg_iou_thr=0.3,
            min_pos_iou=0.3, match_low_quality=True, ignore_iof_thr=-1),
        sampler=dict(
            type='RandomSampler', num=64, pos_fraction=0.5, neg_pos_ub=-1,
            add_gt_as_proposals=False),
        allowed_border=-1, pos_weight=-1, debug=False)
    rpn_proposal = dict(
        nms_pre=100, max_per_img=50, nms=dict(type='nms', iou_threshold=0.7),
        min_bbox_size=0)
    roi = roi_head_cfg(num_sample=32)
    train_rcnn = roi.pop('train_cfg')
    test_rcnn = roi.pop('test_cfg')
    return dict(
        type='CascadeRCNN',
        data_preprocessor=dict(
            type='DetDataPreprocessor', mean=[128.] * 3, std=[64.] * 3,
            bgr_to_rgb=False, pad_mask=True, pad_size_divisor=32),
        backbone=dict(
            type='ResNet', depth=18, base_channels=8, num_stages=4,
            out_indices=(0, 1, 2, 3), frozen_stages=1,
            norm_cfg=dict(type='BN', requires_grad=True), norm_eval=False,
            style='pytorch', init_cfg=None),
        neck=dict(
            type='FPN', in_channels=[8, 16, 32, 64], out_channels=CH,
            num_outs=5),
        rpn_head=dict(
            type='RPNHead', in_channels=CH, feat_channels=CH,
            anchor_generator=dict(
                type='AnchorGenerator', scales=[4], ratios=[0.5, 1.0, 2.0],
                strides=[4, 8, 16, 32, 64]),
            bbox_coder=dict(
                type='DeltaXYWHBBoxCoder', target_means=[0.0] * 4,
                target_stds=[1.0] * 4),
            loss_cls=dict(
                type='CrossEntropyLoss', use_sigmoid=True, loss_weight=1.0),
            loss_bbox=dict(type='SmoothL1Loss', beta=1 / 9, loss_weight=1.)),
        roi_head=roi,
        train_cfg=dict(rpn=rpn_train, rpn_proposal=rpn_proposal,
                       rcnn=train_rcnn),
        test_cfg=dict(rpn=rpn_proposal, rcnn=test_rcnn))


def drawn_batch(seed=0, size=96, num_imgs=2):
    """Images with filled rectangles / ellipses and their instance masks."""
    rng = np.random.default_rng(seed)
    imgs, samples = [], []
    yy, xx = np.mgrid[:size, :size]
    for _ in range(num_imgs):
        img = np.full((3, size, size), 30, np.float32)
        masks, labels = [], []
        for k in range(3):
            x1, y1 = rng.integers(4, size // 2, 2)
            w, h = rng.integers(24, size // 2, 2)
            x2, y2 = min(x1 + w, size - 1), min(y1 + h, size - 1)
            if k % 2:
                cx, cy, rx, ry = (x1 + x2) / 2, (y1 + y2) / 2, \
                    (x2 - x1) / 2, (y2 - y1) / 2
                m = ((xx - cx) / rx)**2 + ((yy - cy) / ry)**2 <= 1
            else:
                m = (xx >= x1) & (xx < x2) & (yy >= y1) & (yy < y2)
            for m_prev in masks:  # later shapes occlude earlier ones
                m_prev &= ~m
            img[:, m] = 80 + 60 * k
            masks.append(m)
            labels.append(k % NUM_CLASSES)
        boxes = []
        for m in masks:  # tight boxes of the visible parts
            ys, xs = np.nonzero(m)
            boxes.append([xs.min(), ys.min(), xs.max() + 1, ys.max() + 1])
        sample = DetDataSample(metainfo=dict(
            img_shape=(size, size), ori_shape=(size, size), pad_shape=(
                size, size), scale_factor=(1., 1.), batch_input_shape=(
                    size, size)))
        sample.gt_instances = InstanceData(
            bboxes=torch.tensor(boxes, dtype=torch.float32),
            labels=torch.tensor(labels),
            masks=BitmapMasks(np.stack(masks).astype(np.uint8), size, size))
        imgs.append(torch.from_numpy(img))
        samples.append(sample)
    return dict(inputs=imgs, data_samples=samples)


def test_roi_head_trains_on_fixed_features():
    """Fast check: the head alone fits fixed features (loss decreases)."""
    torch.manual_seed(0)
    head = MODELS.build(roi_head_cfg(num_sample=32))
    head.init_weights()
    feats, proposals, samples = unit_inputs()
    optim = torch.optim.Adam(head.parameters(), lr=3e-3)
    history = []
    for _ in range(15):
        losses = head.loss(feats, copy.deepcopy(proposals), samples)
        total = sum(v for k, v in losses.items() if 'loss' in k)
        optim.zero_grad()
        total.backward()
        optim.step()
        history.append((total.item(), losses['s2.loss_mask'].item()))
    totals, masks = np.array(history).T
    assert totals[-3:].mean() < 0.8 * totals[:3].mean()
    assert masks[-3:].mean() < masks[:3].mean()


@pytest.mark.slow
def test_tiny_detector_trains_and_predicts():
    """ResNet-18 (8 base channels) + FPN + RPN + our head, 20 iterations on
    two drawn 96x96 images (about 40 s of CPU time)."""
    register_all_modules()  # default scope 'mmdet' for the preprocessor
    torch.manual_seed(0)
    model = MODELS.build(ConfigDict(tiny_detector_cfg()))
    model.init_weights()
    data = model.data_preprocessor(drawn_batch(), training=True)
    optim = torch.optim.Adam(model.parameters(), lr=2e-3)
    history = []
    for _ in range(20):
        losses = model(**data, mode='loss')
        total, log_vars = model.parse_losses(losses)
        optim.zero_grad()
        total.backward()
        optim.step()
        history.append((total.item(), float(log_vars['s2.loss_mask'])))
    assert not any(k.startswith(('s0.loss_mask', 's1.loss_mask'))
                   for k in log_vars)
    totals, masks = np.array(history).T
    assert np.isfinite(totals).all()
    assert totals[-5:].mean() < 0.7 * totals[:3].mean()
    assert masks[-5:].mean() < masks[:3].mean()
    model.eval()
    with torch.no_grad():
        preds = model(**data, mode='predict')
    assert preds[0].pred_instances.masks.shape[1:] == (96, 96)


# --------------------------------------------------------------------------
# Reference: MMDetection's own CascadeRoIHead and FCNMaskHead
# --------------------------------------------------------------------------
#: RoIs sampled per image and stage in the comparisons: fewer than the
#: proposals, so that the sampler's random draws matter.
NUM_SAMPLE = 16


def reference_heads(ours):
    """MMDet's ``CascadeRoIHead`` without masks and an ``FCNMaskHead``,
    holding the weights of ``ours`` (box stages / mask head)."""
    cfg = roi_head_cfg(num_sample=NUM_SAMPLE)
    mask_cfg = cfg.pop('mask_head')
    ref_extractor = MODELS.build(cfg.pop('mask_roi_extractor'))
    cfg['type'] = 'CascadeRoIHead'
    ref = MODELS.build(cfg)
    ref.bbox_head.load_state_dict(ours.bbox_head.state_dict())
    ref_mask = MODELS.build(
        dict(type='FCNMaskHead', **{k: v for k, v in mask_cfg.items()
                                    if k in ('num_convs', 'in_channels',
                                             'conv_out_channels',
                                             'num_classes')}))
    state = {k: v for k, v in ours.mask_head.state_dict().items()
             if not k.startswith('conv_edge.')}
    ref_mask.load_state_dict(state)  # strict: every FCNMaskHead key
    return ref.eval(), ref_mask.eval(), ref_extractor


def randomised_head():
    torch.manual_seed(0)
    head = MODELS.build(roi_head_cfg(num_sample=NUM_SAMPLE))
    head.init_weights()
    with torch.no_grad():  # away from zero biases, more boxes survive
        for p in head.parameters():
            p.add_(0.05 * torch.randn_like(p))
    return head


def test_box_stages_equal_mmdet_cascade_roi_head():
    """Same weights, proposals and seed: the three box stages' losses equal
    MMDet's ``CascadeRoIHead`` (whose mask branch is left out: ours runs a
    mask head on the last stage only)."""
    head = randomised_head()
    ref, _, _ = reference_heads(head)
    feats, proposals, samples = unit_inputs()
    torch.manual_seed(1)
    ours = head.loss(feats, copy.deepcopy(proposals), samples)
    torch.manual_seed(1)
    expected = ref.loss(feats, copy.deepcopy(proposals), samples)
    assert set(expected) == {k for k in ours if 'mask' not in k and
                             'edge' not in k}
    for key, value in expected.items():
        torch.testing.assert_close(ours[key], value, msg=key)
    assert all(expected[f's{i}.loss_bbox'] > 0 for i in range(3))


def test_prediction_equals_mmdet_boxes_and_fcn_mask_head():
    """Final boxes / scores / labels equal MMDet's cascade; the masks equal
    MMDet's ``FCNMaskHead.predict_by_feat`` on those final boxes."""
    head = randomised_head().eval()
    ref, ref_mask, extractor = reference_heads(head)
    feats, proposals, samples = unit_inputs()
    for sample in samples:  # rescaling must reach boxes and masks
        sample.set_metainfo(dict(scale_factor=(0.5, 0.5),
                                 ori_shape=(128, 128)))
    metas = [s.metainfo for s in samples]
    with torch.no_grad():
        ours = head.predict(feats, copy.deepcopy(proposals), samples,
                            rescale=True)
        boxes = ref.predict_bbox(feats, metas, copy.deepcopy(proposals),
                                 ref.test_cfg, rescale=False)
        rois = bbox2roi([res.bboxes for res in boxes])
        logits = ref_mask(extractor(feats[:extractor.num_inputs], rois))
        expected = ref_mask.predict_by_feat(
            logits.split([len(res) for res in boxes]), boxes, metas,
            ref.test_cfg, rescale=True)
    assert sum(len(res) for res in expected) > 5
    for got, exp in zip(ours, expected):
        torch.testing.assert_close(got.bboxes, exp.bboxes)
        torch.testing.assert_close(got.scores, exp.scores)
        assert torch.equal(got.labels, exp.labels)
        assert got.masks.shape == exp.masks.shape == (len(exp), 128, 128)
        # channels_last may move a logit by ~1e-7: allow a flipped pixel
        # at the 0.5 threshold, no more
        assert (got.masks != exp.masks).sum() <= 2
        assert exp.masks.any()
