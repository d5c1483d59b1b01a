"""boundary_loss (fused forward / backward) against plain autograd."""
import numpy as np
import pytest
import torch
from mmdet.registry import MODELS
from scipy import ndimage

import cbnet_mmdet  # noqa: F401  (registers the loss)
from cbnet_mmdet.models.losses.boundary_loss_fused import boundary_loss
from cbnet_mmdet.models.losses.boundary_ops import boundary_loss_autograd


def blob_inputs(num, size, seed, dtype=torch.float32):
    """Realistic RoI masks (smoothed noise thresholded, some instances
    empty / full) and logits that roughly follow them."""
    rng = np.random.default_rng(seed)
    noise = ndimage.gaussian_filter(rng.random((num, size, size)), (0, 3, 3))
    levels = [np.quantile(n, q) for n, q in zip(noise,
                                                rng.uniform(0.2, 0.8, num))]
    targets = noise > np.array(levels)[:, None, None]
    targets[0] = False
    targets[1] = True
    logits = 3 * (targets - 0.5) + rng.normal(0, 2, (num, size, size))
    return (torch.from_numpy(logits).to(dtype),
            torch.from_numpy(targets).to(dtype))


def grads(fn, logits, targets, grad_out, **kwargs):
    logits = logits.detach().clone().requires_grad_()
    loss = fn(logits, targets, **kwargs)
    grad, = torch.autograd.grad(loss, logits, grad_out)
    return loss.detach(), grad


@pytest.mark.parametrize('cfg', [
    dict(dist_stride=2),
    dict(dist_stride=1, lambda_shape=0.7, lambda_edge=3.),
    dict(dist_stride=3, alpha=1., kernel_size=5),
    dict(use_edge=False),
    dict(use_shape=False, dist_stride=2),
    dict(use_shape=False, use_edge=False),
])
def test_gradcheck_float64(cfg):
    """Analytic gradient against finite differences (logits away from the
    0.5 threshold, so that the thresholded masks stay put)."""
    gen = torch.Generator().manual_seed(0)
    sign = torch.randint(0, 2, (3, 6, 7), generator=gen) * 2 - 1
    logits = sign * (0.2 + torch.rand(3, 6, 7, generator=gen,
                                      dtype=torch.float64))
    targets = (torch.rand(3, 6, 7, generator=gen) > 0.5).double()
    targets[0] = 0
    targets[1, 2:4] = 1
    logits.requires_grad_()
    assert torch.autograd.gradcheck(
        lambda x: boundary_loss(x, targets, **cfg), (logits, ))


def test_gradcheck_soft_targets():
    """Targets in (0, 1) that require a gradient (BCE and Dice depend on
    them; the edge term only on ``targets > 0.5``)."""
    gen = torch.Generator().manual_seed(1)
    sign = torch.randint(0, 2, (2, 5, 5), generator=gen) * 2 - 1
    logits = (sign * (0.2 + torch.rand(2, 5, 5, generator=gen,
                                       dtype=torch.float64)))
    targets = torch.rand(2, 5, 5, generator=gen, dtype=torch.float64)
    targets = (0.1 + 0.8 * targets).requires_grad_()
    logits.requires_grad_()
    assert torch.autograd.gradcheck(
        lambda x, t: boundary_loss(x, t, dist_stride=2), (logits, targets))
    # and equal to the plain composition
    loss, grad = torch.autograd.grad(
        boundary_loss(logits, targets).sum(), (logits, targets))
    ref, ref_grad = torch.autograd.grad(
        boundary_loss_autograd(logits, targets).sum(), (logits, targets))
    torch.testing.assert_close(loss, ref)
    torch.testing.assert_close(grad, ref_grad)


@pytest.mark.parametrize('dist_stride', [1, 2])
@pytest.mark.parametrize('size', [28, 27])
def test_matches_plain_composition(dist_stride, size):
    """64 realistic RoIs: value and gradient equal the old formulation."""
    logits, targets = blob_inputs(64, size, seed=size + dist_stride)
    grad_out = torch.rand(64, generator=torch.Generator().manual_seed(0))
    for cfg in (dict(), dict(lambda_shape=0.5, lambda_edge=2.),
                dict(alpha=1.5)):
        loss, grad = grads(boundary_loss, logits, targets, grad_out,
                           dist_stride=dist_stride, **cfg)
        ref, ref_grad = grads(boundary_loss_autograd, logits, targets,
                              grad_out, dist_stride=dist_stride, **cfg)
        torch.testing.assert_close(loss, ref, rtol=1e-5, atol=1e-6)
        torch.testing.assert_close(grad, ref_grad, rtol=1e-4, atol=1e-8)


@pytest.mark.parametrize('case', ['zeros', 'ones', 'saturated'])
def test_constant_masks(case):
    """All-zero / all-one targets with predictions that are empty, full or
    mixed; saturated logits (probabilities exactly 0 / 1 in float32)."""
    logits, _ = blob_inputs(6, 28, seed=3)
    if case == 'saturated':
        logits = logits.sign() * 200
        targets = (logits > 0).float()
        targets[:2] = 1 - targets[:2]  # confidently wrong
    else:
        targets = torch.full_like(logits, float(case == 'ones'))
    logits[0] = -50.  # empty prediction
    logits[1] = 50.  # full prediction
    grad_out = torch.ones(6)
    loss, grad = grads(boundary_loss, logits, targets, grad_out,
                       dist_stride=2)
    ref, ref_grad = grads(boundary_loss_autograd, logits, targets, grad_out,
                          dist_stride=2)
    assert torch.isfinite(loss).all() and torch.isfinite(grad).all()
    torch.testing.assert_close(loss, ref, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(grad, ref_grad, rtol=1e-4, atol=1e-8)


def test_empty_and_dtypes():
    logits = torch.zeros(0, 28, 28, requires_grad=True)
    loss = boundary_loss(logits, torch.zeros(0, 28, 28), dist_stride=2)
    assert loss.shape == (0, )
    loss.sum().backward()
    assert logits.grad.shape == (0, 28, 28)
    # float64 throughout; half precision computed in float32
    logits, targets = blob_inputs(4, 14, seed=0, dtype=torch.float64)
    out = boundary_loss(logits, targets, dist_stride=2)
    assert out.dtype == torch.float64
    torch.testing.assert_close(
        out, boundary_loss_autograd(logits, targets, dist_stride=2))
    half = boundary_loss(logits.half(), targets.half(), dist_stride=2)
    assert half.dtype == torch.float32
    torch.testing.assert_close(
        half.double(),
        boundary_loss_autograd(logits.half().double(), targets, dist_stride=2),
        rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize('weighted', [False, True])
def test_module_gradient_wrt_pred(weighted):
    """CBNetBoundaryAwareLoss (class selection, reduction, loss_weight):
    gradient on the [N, C, H, W] logits equals the plain composition's
    (equal incoming gradients take a shortcut, so both kinds)."""
    logits, targets = blob_inputs(32, 28, seed=5)
    gen = torch.Generator().manual_seed(0)
    label = torch.randint(0, 4, (32, ), generator=gen)
    pred = torch.randn(32, 4, 28, 28, generator=gen)
    pred[torch.arange(32), label] = logits
    weight = torch.rand(32, generator=gen) if weighted else None
    loss_fn = MODELS.build(dict(type='CBNetBoundaryAwareLoss',
                                loss_weight=2.))
    pred = pred.requires_grad_()
    loss = loss_fn(pred, targets, label, weight=weight, avg_factor=7.)
    grad, = torch.autograd.grad(loss, pred)
    ref_pred = pred.detach().clone().requires_grad_()
    ref = boundary_loss_autograd(ref_pred[torch.arange(32), label],
                                 targets, dist_stride=2)
    ref = 2. * (ref if weight is None else ref * weight).sum() / 7.
    ref_grad, = torch.autograd.grad(ref, ref_pred)
    torch.testing.assert_close(loss, ref)
    torch.testing.assert_close(grad, ref_grad, rtol=1e-4, atol=1e-9)


def test_index_and_soft_target_gradients():
    """``index`` selects rows of the logits; target gradients still flow."""
    gen = torch.Generator().manual_seed(2)
    logits = torch.randn(12, 10, 10, generator=gen, dtype=torch.float64)
    index = torch.tensor([3, 0, 7, 11])
    targets = torch.rand(4, 10, 10, generator=gen, dtype=torch.float64)
    logits.requires_grad_()
    targets.requires_grad_()
    grad_out = torch.rand(4, generator=gen, dtype=torch.float64)
    out = boundary_loss(logits, targets, index=index, dist_stride=2)
    grads_ = torch.autograd.grad(out, (logits, targets), grad_out)
    ref = boundary_loss_autograd(logits[index], targets, dist_stride=2)
    ref_grads = torch.autograd.grad(ref, (logits, targets), grad_out)
    torch.testing.assert_close(out, ref)
    for got, want in zip(grads_, ref_grads):
        torch.testing.assert_close(got, want)
    with pytest.raises(ValueError, match='index'):
        boundary_loss(logits, targets, index=index[:3])


def test_no_grad_mode():
    """Same value without autograd (no gradient computed, none kept)."""
    logits, targets = blob_inputs(8, 28, seed=7)
    logits.requires_grad_()
    with torch.no_grad():
        out = boundary_loss(logits, targets, dist_stride=2)
    assert out.grad_fn is None and not out.requires_grad
    torch.testing.assert_close(
        out, boundary_loss(logits, targets, dist_stride=2).detach())


def test_autograd_form_selects_rows_and_takes_empty_input():
    """``boundary_loss_autograd`` (the stock-ops form) with ``index`` is
    the loss of the selected rows, as the fused function's; no instance
    gives an empty result, not an error."""
    logits, targets = blob_inputs(6, 16, seed=3)
    stacked = torch.cat([logits, -logits])  # rows 0-5 and their negation
    index = torch.tensor([6, 1, 8, 3, 10, 5])
    expected = boundary_loss_autograd(stacked[index], targets, dist_stride=2)
    torch.testing.assert_close(
        boundary_loss_autograd(stacked, targets, index=index, dist_stride=2),
        expected)
    torch.testing.assert_close(
        boundary_loss(stacked, targets, index=index, dist_stride=2),
        expected, rtol=1e-5, atol=1e-6)
    empty = boundary_loss_autograd(torch.zeros(0, 16, 16),
                                   torch.zeros(0, 16, 16))
    assert empty.shape == (0, )
    with pytest.raises(ValueError, match='alpha'):
        boundary_loss_autograd(logits, targets, alpha=0)
