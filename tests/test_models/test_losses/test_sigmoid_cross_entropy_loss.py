"""CBNetSigmoidCrossEntropyLoss: per-class BCE of paper eq. (4)."""
import pytest
import torch
import torch.nn.functional as F
from mmdet.registry import MODELS
from mmengine.config import ConfigDict

import cbnet_mmdet  # noqa: F401  (registers the modules)

C = 4


def reference_bce(logits, labels):
    """Eq. (4) by hand: one-hot targets (background all zeros), summed over
    classes, averaged over RoIs."""
    target = torch.zeros_like(logits)
    fg = labels < logits.shape[1]
    target[fg.nonzero()[:, 0], labels[fg]] = 1
    return F.binary_cross_entropy_with_logits(
        logits, target, reduction='sum') / logits.shape[0]


def test_loss_equals_per_class_bce():
    torch.manual_seed(0)
    loss = MODELS.build(dict(type='CBNetSigmoidCrossEntropyLoss',
                             loss_weight=2.0))
    logits = torch.randn(7, C)
    labels = torch.tensor([0, 3, C, 1, C, 2, C])  # C = background
    out = loss(logits, labels, torch.ones(7), avg_factor=7)
    torch.testing.assert_close(out, 2.0 * reference_bce(logits, labels))


def test_background_rows_push_every_class_down():
    loss = MODELS.build(dict(type='CBNetSigmoidCrossEntropyLoss'))
    logits = torch.zeros(1, C, requires_grad=True)
    loss(logits, torch.tensor([C]), torch.ones(1), avg_factor=1).backward()
    assert (logits.grad > 0).all()  # d/dx BCE(x, 0) = sigmoid(x) > 0


def test_activation_and_accuracy():
    loss = MODELS.build(dict(type='CBNetSigmoidCrossEntropyLoss'))
    logits = torch.tensor([[4., -4., -4., -4.], [-6., -6., -6., -6.]])
    act = loss.get_activation(logits)
    assert act.shape == (2, C + 1)
    torch.testing.assert_close(act[:, :C], logits.sigmoid())
    torch.testing.assert_close(act[:, C], (1 - logits.sigmoid()).prod(1))
    acc = loss.get_accuracy(logits, torch.tensor([0, C]))['acc']
    assert acc.item() == pytest.approx(100.0)
    acc = loss.get_accuracy(logits, torch.tensor([1, 0]))['acc']
    assert acc.item() == pytest.approx(0.0)


def test_fixed_arguments_are_refused():
    with pytest.raises(TypeError, match='use_sigmoid is fixed'):
        MODELS.build(dict(type='CBNetSigmoidCrossEntropyLoss',
                          use_sigmoid=False))


def bbox_head():
    head = MODELS.build(
        dict(type='Shared2FCBBoxHead', in_channels=8, fc_out_channels=16,
             roi_feat_size=7, num_classes=C, reg_class_agnostic=True,
             bbox_coder=dict(type='DeltaXYWHBBoxCoder',
                             target_means=[0.] * 4, target_stds=[.1] * 4),
             loss_cls=dict(type='CBNetSigmoidCrossEntropyLoss'),
             loss_bbox=dict(type='SmoothL1Loss', loss_weight=1.0)))
    head.init_weights()
    return head


def test_in_mmdet_bbox_head_loss_and_scores():
    """C classifier outputs; the head's loss is eq. (4); its scores are the
    sigmoid of the logits (not a softmax over C + 1)."""
    torch.manual_seed(0)
    head = bbox_head()
    assert head.fc_cls.out_features == C
    feats = torch.randn(6, 8, 7, 7)
    cls_score, bbox_pred = head(feats)
    labels = torch.tensor([0, 1, C, C, 3, C])
    losses = head.loss(cls_score, bbox_pred,
                       rois=torch.tensor([[0, 0, 0, 10, 10.]] * 6),
                       labels=labels, label_weights=torch.ones(6),
                       bbox_targets=torch.zeros(6, 4),
                       bbox_weights=torch.zeros(6, 4))
    torch.testing.assert_close(losses['loss_cls'],
                               reference_bce(cls_score, labels))
    assert 'acc' in losses
    rois = torch.tensor([[0, 5., 5., 40., 40.]])
    results = head.predict_by_feat(
        rois=(rois, ), cls_scores=(cls_score[:1], ),
        bbox_preds=(bbox_pred[:1], ),
        batch_img_metas=[dict(img_shape=(64, 64))],
        rcnn_test_cfg=ConfigDict(score_thr=0.0,
                                 nms=dict(type='nms', iou_threshold=0.5),
                                 max_per_img=10))[0]
    assert len(results) == C  # one box per class (class-agnostic box)
    expected = cls_score[0].sigmoid()
    torch.testing.assert_close(
        results.scores.sort().values, expected.sort().values)
