"""MaskCallRecorder reads the last mask head's RoIs, labels and logits of
a RoI head's own ``loss`` (MMDet's Mask R-CNN and Cascade heads, CBNet's)
without changing the losses; the reference is a spy on the mask head's
``loss_and_target``, which receives the samples the head trained on."""
import copy
import os.path as osp
from unittest import mock

import mmdet
import pytest
import torch
from mmdet.registry import MODELS
from mmdet.structures.bbox import bbox2roi
from mmdet.testing import demo_mm_inputs, demo_mm_proposals
from mmengine.config import Config, ConfigDict

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.models.detectors.mask_call_recorder import (
    MaskCallRecorder, last_mask_modules, mask_logits_on)

MMDET_MODELS = osp.join(
    osp.dirname(mmdet.__file__), '.mim', 'configs', '_base_', 'models')
C = 16
NUM_CLASSES = 3


def roi_head(base, head_type=None, shared_extractor=False):
    """MMDet's RoI head of ``base`` with 16 channels and 3 classes."""
    model = Config.fromfile(osp.join(MMDET_MODELS, base)).model
    cfg = model.roi_head
    if head_type is not None:
        cfg.type = head_type
    heads = cfg.bbox_head if isinstance(cfg.bbox_head, list) \
        else [cfg.bbox_head]
    for h in heads:
        h.update(in_channels=C, fc_out_channels=32, num_classes=NUM_CLASSES)
    cfg.bbox_roi_extractor.out_channels = C
    cfg.mask_roi_extractor.out_channels = C
    if shared_extractor:  # the 7x7 box features: 14x14 mask targets
        cfg.pop('mask_roi_extractor')
        rcnns = model.train_cfg.rcnn
        for rcnn in rcnns if isinstance(rcnns, list) else [rcnns]:
            rcnn.mask_size = 14
    cfg.mask_head.update(in_channels=C, conv_out_channels=C, num_convs=1,
                         num_classes=NUM_CLASSES)
    cfg.train_cfg = model.train_cfg.rcnn
    cfg.test_cfg = model.test_cfg.rcnn
    return MODELS.build(ConfigDict(cfg))


def inputs(num_items=(3, 2), size=64):
    shapes = [(3, size, size)] * len(num_items)
    packed = demo_mm_inputs(
        batch_size=len(num_items), image_shapes=shapes,
        num_items=list(num_items), num_classes=NUM_CLASSES, with_mask=True)
    torch.manual_seed(1)
    feats = tuple(
        torch.rand(len(num_items), C, size // s, size // s)
        for s in (4, 8, 16, 32))
    return feats, demo_mm_proposals(shapes, 40), packed['data_samples']


HEADS = [
    ('mask-rcnn_r50_fpn.py', None),
    ('cascade-mask-rcnn_r50_fpn.py', None),
    ('cascade-mask-rcnn_r50_fpn.py', 'CBNetCascadeRoIHead'),
    # MMDet's cascade sharing the box extractor of each stage, and CBNet's
    # sharing the last stage's
    ('cascade-mask-rcnn_r50_fpn.py', 'shared'),
    ('cascade-mask-rcnn_r50_fpn.py', 'CBNetCascadeRoIHead-shared'),
]


def build_head(base, head_type):
    torch.manual_seed(0)
    if head_type and head_type.endswith('shared'):
        return roi_head(base, head_type.split('-')[0] if '-' in head_type
                        else None, shared_extractor=True)
    return roi_head(base, head_type)


@pytest.mark.parametrize('base,head_type', HEADS)
def test_records_the_last_mask_call_and_changes_no_loss(base, head_type):
    head = build_head(base, head_type)
    _, mask_head = last_mask_modules(head)
    feats, proposals, samples = inputs()
    torch.manual_seed(7)  # the random samplers draw the same samples
    expected = head.loss(feats, copy.deepcopy(proposals), samples)
    calls = []
    original = mask_head.loss_and_target

    def spy(mask_preds, sampling_results, *args, **kwargs):
        calls.append((mask_preds, sampling_results))
        return original(mask_preds, sampling_results, *args, **kwargs)

    torch.manual_seed(7)
    with mock.patch.object(mask_head, 'loss_and_target', side_effect=spy), \
            MaskCallRecorder(head) as recorder:
        losses = head.loss(feats, copy.deepcopy(proposals), samples)
    assert set(losses) == set(expected)
    for name in expected:
        torch.testing.assert_close(losses[name], expected[name], msg=name)
    mask_preds, sampling_results = calls[-1]
    call = recorder.last_call()
    assert call.mask_preds is mask_preds  # the logits, with their graph
    assert call.mask_preds.requires_grad
    torch.testing.assert_close(
        call.rois, bbox2roi([r.pos_priors for r in sampling_results]))
    assert torch.equal(
        call.labels, torch.cat([r.pos_gt_labels for r in sampling_results]))
    assert len(call.rois) == len(call.mask_preds) > 0
    assert call.labels.max() > 0  # not all class 0: real labels were read
    # the hooks are gone after the block
    assert not mask_head._forward_hooks
    assert not mask_head.loss_mask._forward_pre_hooks
    assert all(not m._forward_hooks for m in head.modules())


@pytest.mark.parametrize('base,head_type', HEADS)
def test_mask_logits_on_runs_the_last_stage(base, head_type):
    """The teacher's side: the last mask stage's extractor and head."""
    head = build_head(base, head_type).eval()
    feats, _, _ = inputs()
    rois = torch.tensor([[0., 2., 2., 30., 40.], [1., 10., 5., 60., 60.]])
    stage = head.num_stages - 1 if hasattr(head, 'num_stages') else None
    with torch.no_grad():
        got = mask_logits_on(head, feats, rois)
        if stage is None:
            ref = head._mask_forward(feats, rois)['mask_preds']
        else:
            ref = head._mask_forward(stage, feats, rois)['mask_preds']
    assert got.shape[:2] == (2, NUM_CLASSES) and got.shape[2] in (14, 28)
    torch.testing.assert_close(got, ref)


def test_no_call_and_empty_call():
    head = build_head('cascade-mask-rcnn_r50_fpn.py', 'CBNetCascadeRoIHead')
    with MaskCallRecorder(head) as recorder:
        pass
    assert recorder.last_call() is None
    # images without objects: no positive RoI, no labels, empty logits
    feats, proposals, samples = inputs()
    for sample in samples:
        sample.gt_instances = sample.gt_instances[:0]
    with MaskCallRecorder(head) as recorder:
        head.loss(feats, proposals, samples)
    call = recorder.last_call()
    assert call.rois.shape == (0, 5) and call.labels.shape == (0, )
    assert call.mask_preds.shape[0] == 0


def test_refuses_heads_whose_mask_rois_cannot_be_read():
    # Mask R-CNN sharing the box extractor crops the box features
    head = roi_head('mask-rcnn_r50_fpn.py', shared_extractor=True)
    with pytest.raises(TypeError, match='mask_roi_extractor'):
        MaskCallRecorder(head)
    with pytest.raises(TypeError, match='Linear'):
        last_mask_modules(torch.nn.Linear(1, 1))
    head = build_head('mask-rcnn_r50_fpn.py', None)
    del head.mask_head.loss_mask
    with pytest.raises(TypeError, match='loss_mask'):
        last_mask_modules(head)
    # a mask head run on features its extractor did not give
    head = build_head('mask-rcnn_r50_fpn.py', None)
    with MaskCallRecorder(head), \
            pytest.raises(RuntimeError, match='extractor'):
        head.mask_head(torch.rand(2, C, 14, 14))
