import pytest
import torch
from mmdet.registry import MODELS

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.models.losses.distill_loss import binary_mask_temperature


def reference_loss(student, teacher):
    """Formula (11) written with an explicit 2-class softmax per pixel.

    Per pixel the class logits are [0, z]; tau per RoI is the mean over
    pixels of the teacher's max class probability; the loss is
    CE(p_t, p_s) - H(p_t), averaged over pixels, then over RoIs.
    """
    def two_class(z):
        return torch.stack([torch.zeros_like(z), z], dim=-1)

    t_prob = torch.softmax(two_class(teacher), dim=-1)
    tau = t_prob.max(dim=-1).values.flatten(1).mean(1)
    tau = tau.view(-1, *([1] * (teacher.dim() - 1)))
    log_p_s = torch.log_softmax(two_class(student / tau), dim=-1)
    log_p_t = torch.log_softmax(two_class(teacher / tau), dim=-1)
    p_t = log_p_t.exp()
    ce = -(p_t * log_p_s).sum(-1)
    entropy = -(p_t * log_p_t).sum(-1)
    return (ce - entropy).flatten(1).mean(1)


def build(**kwargs):
    return MODELS.build(dict(type='CBNetDistillLoss', **kwargs))


def test_matches_reference_and_golden():
    torch.manual_seed(0)
    student = torch.randn(6, 28, 28) * 3
    teacher = torch.randn(6, 28, 28) * 3
    loss = build()
    expected = reference_loss(student.double(), teacher.double())
    torch.testing.assert_close(
        loss(student, teacher, reduction_override='none'),
        expected.float(),
        rtol=1e-5,
        atol=1e-6)
    torch.testing.assert_close(loss(student, teacher), expected.mean().float())
    # golden value with the fixed seed: a silent change of the formula
    # (tau, reduction, KL vs CE) breaks it
    assert loss(student, teacher).item() == pytest.approx(1.26626, abs=1e-4)


def test_zero_for_identical_logits_positive_otherwise():
    torch.manual_seed(1)
    logits = torch.randn(4, 1, 28, 28) * 5
    loss = build()
    assert loss(logits, logits.clone()).abs().item() < 1e-6
    assert loss(logits, logits + 0.5 * torch.randn_like(logits)).item() > 0
    # per RoI: only the changed RoI is positive
    other = logits.clone()
    other[2] = -other[2]
    per_roi = loss(logits, other, reduction_override='none')
    assert per_roi[2] > 0.1
    assert per_roi[[0, 1, 3]].abs().max() < 1e-6


def test_gradient_flows_only_to_student():
    torch.manual_seed(2)
    student = torch.randn(3, 14, 14, requires_grad=True)
    teacher = torch.randn(3, 14, 14, requires_grad=True)
    build()(student, teacher).backward()
    assert student.grad is not None and student.grad.abs().sum() > 0
    assert teacher.grad is None


def test_temperature_range():
    confident = torch.full((1, 28, 28), 50.)
    unsure = torch.zeros(1, 28, 28)
    half = torch.cat([torch.full((1, 14, 28), 50.),
                      torch.zeros(1, 14, 28)], 1)
    tau = binary_mask_temperature(torch.cat([confident, unsure, half]))
    torch.testing.assert_close(tau, torch.tensor([1.0, 0.5, 0.75]))


def test_weight_avg_factor_loss_weight_reduction():
    torch.manual_seed(3)
    student, teacher = torch.randn(4, 8, 8), torch.randn(4, 8, 8)
    per_roi = build(reduction='none')(student, teacher)
    assert per_roi.shape == (4, )
    weight = torch.tensor([1., 0., 2., 1.])
    torch.testing.assert_close(
        build(loss_weight=2.0)(student, teacher, weight=weight,
                               avg_factor=5.),
        2.0 * (per_roi * weight).sum() / 5.)
    torch.testing.assert_close(
        build()(student, teacher, reduction_override='sum'), per_roi.sum())


def test_empty_input_is_zero_and_connected():
    student = torch.zeros(0, 28, 28, requires_grad=True)
    loss = build()(student, torch.zeros(0, 28, 28))
    assert loss.item() == 0
    loss.backward()
    assert student.grad is not None
    assert build()(student, torch.zeros(0, 28, 28),
                   reduction_override='none').shape == (0, )


def test_bad_input():
    with pytest.raises(ValueError, match='differ in shape'):
        build()(torch.zeros(2, 28, 28), torch.zeros(3, 28, 28))
    with pytest.raises(ValueError, match='Tensor\\[N'):
        build()(torch.zeros(4), torch.zeros(4))
    with pytest.raises(ValueError, match='reduction'):
        build(reduction='avg')
    with pytest.raises(ValueError, match='reduction'):
        build()(
            torch.zeros(2, 4, 4),
            torch.zeros(2, 4, 4),
            reduction_override='max')
