"""CBNetBoundaryMaskHead: edge output, edge supervision, MMDet contract."""
import numpy as np
import pytest
import torch
import torch.nn.functional as F
from mmengine.config import ConfigDict
from mmdet.registry import MODELS
from mmdet.testing import (demo_mm_inputs, demo_mm_proposals,
                           demo_mm_sampling_results)
from scipy import ndimage

import cbnet_mmdet  # noqa: F401  (registers the modules)


def build(**kwargs):
    cfg = dict(
        type='CBNetBoundaryMaskHead', num_convs=1, in_channels=8,
        conv_out_channels=8, num_classes=3)
    cfg.update(kwargs)
    head = MODELS.build(cfg)
    head.init_weights()
    return head


def sampled(num_items=3):
    packed = demo_mm_inputs(
        batch_size=1, image_shapes=[(3, 64, 64)], num_items=[num_items],
        num_classes=3, with_mask=True)
    gt = [packed['data_samples'][0].gt_instances]
    sampling = demo_mm_sampling_results(
        demo_mm_proposals([(3, 64, 64)], 20), gt)
    return sampling, gt


def test_forward_outputs():
    head = build()
    feats = torch.rand(5, 8, 14, 14)
    mask = head(feats)  # MMDet's single-output contract
    assert isinstance(mask, torch.Tensor) and mask.shape == (5, 3, 28, 28)
    mask2, edge = head(feats, return_edge=True)
    torch.testing.assert_close(mask, mask2)
    assert edge.shape == (5, 1, 28, 28)
    assert head.with_edge
    agnostic, _ = build(class_agnostic=True)(feats, return_edge=True)
    assert agnostic.shape == (5, 1, 28, 28)


@pytest.mark.parametrize('num_rois', [0, 7])
def test_channels_last_matches_fcn_mask_head(num_rois):
    """The channels_last path (forced: by default CPU inference only)
    computes FCNMaskHead's function, returns contiguous NCHW logits, and
    passes the same gradients back."""
    from mmdet.models.roi_heads.mask_heads import FCNMaskHead
    torch.manual_seed(0)
    head = build(num_convs=2, channels_last=True)
    ref = FCNMaskHead(num_convs=2, in_channels=8, conv_out_channels=8,
                      num_classes=3)
    ref.load_state_dict(head.state_dict(), strict=False)
    feats = torch.rand(num_rois, 8, 14, 14, requires_grad=True)
    mask, edge = head(feats, return_edge=True)
    assert mask.is_contiguous() and edge.is_contiguous()
    expected = ref(feats)
    torch.testing.assert_close(mask, expected, rtol=1e-5, atol=1e-5)
    plain = build(num_convs=2, channels_last=False)
    plain.load_state_dict(head.state_dict())
    torch.testing.assert_close(plain(feats), expected, rtol=0, atol=0)
    if num_rois:
        g = torch.randn_like(mask)
        grad, = torch.autograd.grad((mask * g).sum(), feats)
        grad_ref, = torch.autograd.grad((expected * g).sum(), feats)
        torch.testing.assert_close(grad, grad_ref, rtol=1e-4, atol=1e-6)


def test_edge_loss_against_scipy_contours():
    torch.manual_seed(0)
    head = build()
    sampling, gt = sampled()
    num_pos = sum(len(s.pos_priors) for s in sampling)
    mask_preds, edge_preds = head(
        torch.rand(num_pos, 8, 14, 14), return_edge=True)
    out = head.loss_and_target(mask_preds, sampling, gt,
                               ConfigDict(mask_size=28), edge_preds=edge_preds)
    losses = out['loss_mask']
    assert set(losses) == {'loss_mask', 'loss_edge'}
    targets = out['mask_targets'].numpy() > 0.5
    contours = np.stack([
        t & ~ndimage.binary_erosion(t, np.ones((3, 3)), border_value=0)
        for t in targets
    ])
    ref = F.binary_cross_entropy_with_logits(
        edge_preds[:, 0], torch.from_numpy(contours).float())
    torch.testing.assert_close(losses['loss_edge'].squeeze(), ref)
    sum(losses.values()).backward()
    assert head.conv_edge.weight.grad.abs().sum() > 0


def test_no_positive_rois_and_no_edge_loss():
    head = build()
    sampling, gt = sampled()
    for res in sampling:  # drop all positives
        res.pos_inds = res.pos_inds[:0]
        res.pos_priors = res.pos_priors[:0]
        res.pos_gt_labels = res.pos_gt_labels[:0]
        res.pos_assigned_gt_inds = res.pos_assigned_gt_inds[:0]
    mask_preds, edge_preds = head(torch.rand(0, 8, 14, 14), return_edge=True)
    losses = head.loss_and_target(mask_preds, sampling, gt,
                                  ConfigDict(mask_size=28),
                                  edge_preds=edge_preds)['loss_mask']
    assert losses['loss_edge'].item() == 0 and losses['loss_mask'].item() == 0


def test_without_edge_loss_there_is_no_edge_branch():
    """loss_edge=None (the paper configs): a plain FCN mask head."""
    head = build(loss_edge=None)
    assert not head.with_edge and not hasattr(head, 'conv_edge')
    head.init_weights()
    sampling, gt = sampled()
    num_pos = sum(len(s.pos_priors) for s in sampling)
    mask_preds = head(torch.rand(num_pos, 8, 14, 14))
    losses = head.loss_and_target(mask_preds, sampling, gt,
                                  ConfigDict(mask_size=28))['loss_mask']
    assert set(losses) == {'loss_mask'}
    with pytest.raises(ValueError, match='no edge branch'):
        head(torch.rand(1, 8, 14, 14), return_edge=True)


def test_bad_edge_kernel():
    with pytest.raises(ValueError, match='edge_kernel'):
        build(edge_kernel=2)
