"""The RoI-head losses written out with the heads' parts: identical to the
heads' own ``loss`` (MMDet's Mask R-CNN and Cascade heads, CBNet's), and the
returned mask record is what the mask head was trained on."""
import copy
import os.path as osp
from unittest import mock

import mmdet
import pytest
import torch
from mmdet.models.roi_heads import CascadeRoIHead
from mmdet.registry import MODELS
from mmdet.structures.bbox import bbox2roi
from mmdet.testing import demo_mm_inputs, demo_mm_proposals
from mmengine.config import Config, ConfigDict

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.models.roi_heads.roi_head_losses import (
    mask_record_losses_of, roi_losses_with_mask_record)

MMDET_MODELS = osp.join(
    osp.dirname(mmdet.__file__), '.mim', 'configs', '_base_', 'models')
C = 16
NUM_CLASSES = 3


def roi_head(base, head_type=None):
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
    ('mask-rcnn_r50_fpn.py', None, None),
    ('cascade-mask-rcnn_r50_fpn.py', None, 2),
    ('cascade-mask-rcnn_r50_fpn.py', 'CBNetCascadeRoIHead', 2),
]


@pytest.mark.parametrize('base,head_type,last_stage', HEADS)
def test_losses_equal_the_heads_own_loss(base, head_type, last_stage):
    torch.manual_seed(0)
    head = roi_head(base, head_type)
    feats, proposals, samples = inputs()
    torch.manual_seed(7)  # the random samplers draw the same samples
    expected = head.loss(feats, copy.deepcopy(proposals), samples)
    torch.manual_seed(7)
    losses, record = roi_losses_with_mask_record(
        head, feats, copy.deepcopy(proposals), samples)
    assert set(losses) == set(expected)
    for name in expected:
        torch.testing.assert_close(losses[name], expected[name], msg=name)
    assert record.stage == last_stage
    assert any('loss_mask' in name for name in losses)


@pytest.mark.parametrize('base,head_type,last_stage', HEADS)
def test_record_is_what_the_last_mask_call_trained_on(base, head_type,
                                                      last_stage):
    torch.manual_seed(0)
    head = roi_head(base, head_type)
    mask_head = head.mask_head[-1] \
        if isinstance(head.mask_head, torch.nn.ModuleList) else head.mask_head
    feats, proposals, samples = inputs()
    calls = []
    original = mask_head.loss_and_target

    def spy(mask_preds, sampling_results, *args, **kwargs):
        calls.append((mask_preds, sampling_results))
        return original(mask_preds, sampling_results, *args, **kwargs)

    with mock.patch.object(mask_head, 'loss_and_target', side_effect=spy):
        _, record = roi_losses_with_mask_record(head, feats, proposals,
                                                samples)
    mask_preds, sampling_results = calls[-1]
    assert record.mask_results['mask_preds'] is mask_preds
    assert record.sampling_results is sampling_results
    rois = bbox2roi([r.pos_priors for r in record.sampling_results])
    assert len(rois) == len(mask_preds) > 0


def test_heads_that_override_loss_are_refused():

    class OwnLoss(CascadeRoIHead):

        def loss(self, *args, **kwargs):
            return dict()

    head = roi_head('cascade-mask-rcnn_r50_fpn.py')
    head.__class__ = OwnLoss
    assert mask_record_losses_of(head) is None
    feats, proposals, samples = inputs()
    with pytest.raises(TypeError, match='OwnLoss'):
        roi_losses_with_mask_record(head, feats, proposals, samples)
    with pytest.raises(TypeError, match='Linear'):
        roi_losses_with_mask_record(torch.nn.Linear(1, 1), feats, proposals,
                                    samples)
