"""The boundary-aware mask loss, forward and backward fused (the form that
trains).

:func:`boundary_loss` is :func:`.boundary_ops.boundary_loss_autograd` (the
readable definition, and the paper's reading, in :mod:`.boundary_ops`)
computed in one ``torch.autograd.Function``.

Speed (CPU): :func:`boundary_loss` computes the whole loss (BCE, Dice,
edge term) and its gradient in one ``torch.autograd.Function``; masks and
distance maps run on flat / cell-major layouts (contiguous operands), the
distance transforms in int16, with in-place operations, because on CPU
every fresh full-size buffer (allocation, page faults) and every strided
operand costs more than the arithmetic on it;
``tools/analysis_tools/benchmark_mask_loss.py`` measures it.
"""
import functools
import math
from typing import Optional

import torch
from torch import Tensor
from torch.autograd.function import once_differentiable

from .boundary_ops import (_check_edge_args, _check_masks, _check_pair,
                           _coarsen, _edt_dtype, _erode_flat,
                           _squared_edt_hwm, mask_diagonal)

__all__ = ['boundary_loss']


def _edge_weight_rows(masks: Tensor,
                      alpha: float,
                      kernel_size: int,
                      stride: int,
                      dtype: torch.dtype,
                      scale: float = 1.) -> Tensor:
    """Weights ``(d_g / D)^alpha + (d_p / D)^alpha`` of the edge term.

    Args:
        masks (Tensor): bool ``Tensor[2 N, H, W]``: the binary targets,
            then the thresholded predictions.
        alpha (float): Distance exponent.
        kernel_size (int): Contour erosion window.
        stride (int): Grid coarsening of the distance maps.
        dtype (torch.dtype): Output dtype.
        scale (float): Factor applied to the weights. Defaults to 1.

    Returns:
        Tensor: ``Tensor[ceil(H / stride), N, W]``, one row per ``stride``
        pixel rows (nearest upsampling along W done, along H left to the
        caller). No gradient.
    """
    num, h, w = masks.shape
    num //= 2
    hc, wc = -(-h // stride), -(-w // stride)
    contours = torch.gt(masks, _erode_flat(masks, kernel_size // 2))
    dist_sq = _squared_edt_hwm(
        _coarsen(contours, stride, _edt_dtype(hc, wc)))
    # squared distances (coarse cells^2) -> (d / D)^2, capped at 1
    weight = dist_sq.to(torch.float32).mul_(
        stride**2 / mask_diagonal(h, w)**2).clamp_max_(1.)
    if alpha != 2:
        weight = weight.pow_(alpha / 2)
    # (d_g / D)^alpha + (d_p / D)^alpha per cell: [hc, wc, N]
    weight = torch.add(weight[..., :num], weight[..., num:]).to(dtype)
    if scale != 1:
        weight.mul_(scale)
    # upsampling along W and the move of N before W in one product with
    # a 0 / 1 matrix: exact, and much faster on CPU than a strided copy
    return torch.matmul(
        weight.transpose(1, 2),
        _upsampling_matrix(w, stride, weight.dtype, weight.device))


@functools.lru_cache(maxsize=32)
def _upsampling_matrix(size: int, stride: int, dtype: torch.dtype,
                       device: torch.device) -> Tensor:
    """0 / 1 ``Tensor[ceil(size / stride), size]``: ``coarse @ matrix``
    repeats each coarse column ``stride`` times (nearest upsampling). A
    shared constant, never written to."""
    idx = torch.arange(size, device=device)
    matrix = torch.zeros(-(-size // stride), size, dtype=dtype, device=device)
    matrix[idx // stride, idx] = 1
    return matrix


def _mul_row_weights(values: Tensor,
                     weight: Tensor,
                     stride: int,
                     out: Optional[Tensor] = None) -> Tensor:
    """``values * weight`` with one weight row per ``stride`` rows.

    Args:
        values (Tensor): ``Tensor[N, H, W]``, contiguous.
        weight (Tensor): ``Tensor[N, ceil(H / stride), W]`` (any strides).
        stride (int): Rows per weight row.
        out (Tensor, optional): Contiguous ``Tensor[N, H, W]`` to write to.

    Returns:
        Tensor: ``Tensor[N, H, W]``, contiguous.
    """
    num, h, w = values.shape
    if out is None:
        out = torch.empty_like(values)
    # one product per row of a cell: faster on CPU than a broadcast over
    # a size-`stride` dimension
    for i in range(stride):
        rows = -(-(h - i) // stride)
        torch.mul(values[:, i::stride], weight[:, :rows],
                  out=out[:, i::stride])
    return out


def boundary_loss(logits: Tensor,
                  targets: Tensor,
                  lambda_shape: float = 1.0,
                  use_shape: bool = True,
                  lambda_edge: float = 1.0,
                  use_edge: bool = True,
                  alpha: float = 2.0,
                  kernel_size: int = 3,
                  dist_stride: int = 1,
                  index: Optional[Tensor] = None) -> Tensor:
    """Per-instance boundary-aware loss, forward and backward fused.

    ``lambda_shape * (BCE + use_shape * (1 - DSC)) + use_edge *
    lambda_edge * L_edge`` of each instance, where ``BCE`` is the pixel
    mean of ``binary_cross_entropy_with_logits``, ``DSC`` is
    :func:`dice_coefficient` of ``sigmoid(logits)`` and ``L_edge`` is
    :func:`distance_weighted_error`. The same value and gradient as
    composing those functions with autograd, up to float rounding
    (``tests/test_models/test_losses/test_boundary_loss_fused.py``), at a
    fraction of the cost: one ``torch.autograd.Function`` whose forward
    pass also computes the gradient (every factor but the incoming one is
    known there), the target-only work done once without autograd, few
    full-size buffers (on CPU a fresh buffer costs more than the
    arithmetic on it) and the distance transforms in int16.

    Args:
        logits (Tensor): Mask logits, ``Tensor[N, H, W]``, or
            ``Tensor[M, H, W]`` with ``index``; float16 / bfloat16 are
            computed in float32.
        targets (Tensor): Targets in ``[0, 1]``, ``Tensor[N, H, W]`` (the
            edge term uses ``targets > 0.5``).
        lambda_shape (float): Weight of BCE + Dice. Defaults to 1.0.
        use_shape (bool): Add ``1 - DSC``. Defaults to True.
        lambda_edge (float): Weight of the edge term. Defaults to 1.0.
        use_edge (bool): Add the edge term. Defaults to True.
        alpha (float): Distance exponent of the edge term. Defaults to 2.
        kernel_size (int): Contour erosion window. Defaults to 3.
        dist_stride (int): Grid coarsening of the distance maps (see
            :func:`squared_distance_to_set`). Defaults to 1.
        index (Tensor, optional): ``Tensor[N]`` rows of ``logits`` to use,
            i.e. the loss of ``logits.index_select(0, index)`` (e.g. each
            RoI's class channel of ``Tensor[N * C, H, W]`` logits), with
            the gradient scattered into ``logits``'s shape directly.

    Returns:
        Tensor: ``Tensor[N]``. Not twice differentiable.
    """
    if index is not None and (logits.dtype in (torch.float16,
                                               torch.bfloat16)
                              or not logits.requires_grad):
        logits, index = logits.index_select(0, index), None
    if index is None:
        _check_pair('logits', logits, 'targets', targets)
    else:
        _check_masks('logits', logits)
        _check_masks('targets', targets)
        if (tuple(index.shape) != (len(targets), )
                or logits.shape[1:] != targets.shape[1:]):
            raise ValueError(
                f'index {tuple(index.shape)} must select one logits row '
                f'{tuple(logits.shape[1:])} per target '
                f'{tuple(targets.shape)}')
    _check_edge_args(alpha, kernel_size, dist_stride)
    if logits.dtype in (torch.float16, torch.bfloat16):
        logits = logits.float()  # e.g. under autocast: sums, products
    targets = targets.to(logits.dtype)
    if len(targets) == 0:
        if index is not None:
            logits = logits.index_select(0, index)
        return logits.sum((1, 2)) + targets.sum((1, 2))
    if not torch.is_grad_enabled():
        # the forward pass computes the gradient for inputs that require
        # one, which no_grad mode does not tell a Function
        logits, targets = logits.detach(), targets.detach()
    edge = (alpha, kernel_size, int(dist_stride)) if use_edge else None
    return _BoundaryLoss.apply(logits, index, targets, float(lambda_shape),
                               bool(use_shape), float(lambda_edge), edge)


def _log_chunks(numel: int, dtype: torch.dtype) -> int:
    """Number of chunks that ``numel`` values in ``[0.5, 1]`` are split
    into so that the product of each chunk stays a normal ``dtype``
    number (``sum(log(q)) = sum(log(prod(chunk)))``: a few logarithms
    instead of one per value)."""
    longest = int(-math.log2(torch.finfo(dtype).tiny))  # 0.5^k >= tiny
    return -(-numel // longest)


class _BoundaryLoss(torch.autograd.Function):
    """Fused forward / backward of :func:`boundary_loss`.

    Per pixel, with ``p = sigmoid(x)``, ``g`` the target, ``b = g > 0.5``
    and ``w`` the edge term's distance weights (constants)::

        BCE   = softplus(x) - x g = max(x, 0) - x g - log(max(p, 1 - p))
        dL/dx = ls / HW (p - g)
                + p (1 - p) (-ls us 2 / den (g - DSC p)
                             + le / HW w (p - b))
        dL/dg = -ls / HW x - ls us 2 / den (p - DSC g)

    with ``den = sum(p^2 + g^2)``. The sum of the logarithms is taken as
    the logarithm of products of chunks (exact up to rounding, see
    :func:`_log_chunks`): ``softplus`` itself is several times slower on
    CPU than ``sigmoid``. Every factor of these gradients but the
    incoming per-instance one is known in the forward pass, which
    therefore computes them while its buffers are in cache and keeps
    only them; the backward pass is one product.
    """

    @staticmethod
    def forward(ctx, logits: Tensor, index: Optional[Tensor],
                targets: Tensor, lambda_shape: float, use_shape: bool,
                lambda_edge: float, edge) -> Tensor:
        ctx.index, ctx.logits_shape = index, logits.shape
        if index is not None:
            logits = logits.index_select(0, index)
        num, h, w = logits.shape
        hw = h * w
        x = logits.reshape(num, hw)
        g = targets.reshape(num, hw)
        p = torch.sigmoid(x)
        # the buffer of the sums below (every full-size buffer counts:
        # the working set is larger than the CPU caches)
        buf = torch.empty_like(p)
        # BCE: sum(max(x, 0) - x g) - sum(log(max(p, 1 - p)))
        bce = torch.clamp_min(x, 0, out=buf).addcmul_(x, g, value=-1).sum(1)
        torch.maximum(torch.sub(p.new_ones(()), p, out=buf), p, out=buf)
        chunks = _log_chunks(hw, p.dtype)
        if hw % chunks:  # pad with ones (log 1 = 0)
            q = buf.new_ones(num, chunks * -(-hw // chunks))
            q[:, :hw] = buf
        else:
            q = buf
        bce -= q.view(num, chunks, -1).prod(2).log_().sum(1)
        loss = bce.mul_(lambda_shape / hw)
        if use_shape:
            inter = torch.mul(p, g, out=buf).sum(1)
            # sums of squares as squared norms: one pass each
            den = torch.linalg.vector_norm(p, dim=1).square_()
            den += torch.linalg.vector_norm(g, dim=1).square_()
            tiny = torch.finfo(p.dtype).tiny
            den_c = den.clamp_min(tiny)
            dice = torch.where(den > 0, 2 * inter / den_c,
                               torch.ones_like(den))
            loss += lambda_shape * (1 - dice)
            # d(1 - DSC)/dp = -(coef_g g - coef_p p): 2 / den and
            # 2 DSC / den where den > 0 (the clamp passes no gradient to
            # den below tiny), else 0
            coef_g = torch.where(den > 0, 2 / den_c, torch.zeros_like(den))
            coef_p = coef_g * dice * (den >= tiny)
        grad_x = None
        if edge is not None:
            alpha, kernel_size, stride = edge
            # binary target and thresholded prediction: comparisons into
            # float and float -> bool copies are 4x faster on CPU than
            # comparisons into bool; grad_x is a buffer until d L_edge / dp
            masks = torch.empty(
                2 * num, h, w, dtype=torch.bool, device=p.device)
            grad_x = torch.ge(p, 0.5, out=torch.empty_like(p))
            masks[num:].view(num, hw).copy_(grad_x)
            target_bin = torch.gt(g, 0.5, out=buf)
            masks[:num].view(num, hw).copy_(target_bin)
            # weights scaled by le / HW: the product with the error is
            # then d L_edge / dp, and L_edge half its sum against the error
            weight = _edge_weight_rows(masks, alpha, kernel_size, stride,
                                       p.dtype, lambda_edge / hw)
            diff = torch.sub(p, target_bin, out=target_bin).view(num, h, w)
            grad_x = _mul_row_weights(
                diff, weight.permute(1, 0, 2), stride,
                out=grad_x.view(num, h, w)).view(num, hw)
            loss += diff.view(num, hw).mul_(grad_x).sum(1).mul_(0.5)
        if ctx.needs_input_grad[0]:
            # d L / dp without the BCE, then d / dx and the BCE's p - g
            if use_shape:
                col_g = (-lambda_shape * coef_g)[:, None]
                col_p = (lambda_shape * coef_p)[:, None]
                if grad_x is None:
                    grad_x = torch.mul(g, col_g)
                else:
                    grad_x.addcmul_(g, col_g)
                grad_x.addcmul_(p, col_p)
            bce_coef = lambda_shape / hw
            if grad_x is None:
                grad_x = torch.sub(p, g).mul_(bce_coef)
            else:
                torch.ops.aten.sigmoid_backward.grad_input(
                    grad_x, p, grad_input=grad_x)
                grad_x.add_(p, alpha=bce_coef).sub_(g, alpha=bce_coef)
            grad_x = grad_x.view(num, h, w)
        else:
            grad_x = None
        grad_g = None
        if ctx.needs_input_grad[2]:
            grad_g = torch.mul(x, -lambda_shape / hw)
            if use_shape:
                grad_g.addcmul_(p, (-lambda_shape * coef_g)[:, None])
                grad_g.addcmul_(g, (lambda_shape * coef_p)[:, None])
            grad_g = grad_g.view(num, h, w)
        ctx.save_for_backward(grad_x, grad_g)
        return loss

    @staticmethod
    @once_differentiable
    def backward(ctx, grad: Tensor):
        grad_x, grad_g = ctx.saved_tensors
        col = grad[:, None, None]
        if grad_x is not None and ctx.index is not None:
            # the gradient of index_select, without an intermediate product
            # where every instance has the same incoming gradient (mean
            # reduction; checked on CPU only, it would synchronise a GPU)
            out = grad_x.new_zeros(ctx.logits_shape)
            if grad.device.type == 'cpu' and grad.min() == grad.max():
                grad_x = out.index_add_(
                    0, ctx.index, grad_x, alpha=grad[0].item())
            else:
                grad_x = out.index_add_(0, ctx.index, grad_x * col)
        elif grad_x is not None:
            grad_x = grad_x * col
        return (grad_x, None, None if grad_g is None else grad_g * col, None,
                None, None, None)
