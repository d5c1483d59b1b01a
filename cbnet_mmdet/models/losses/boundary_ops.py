"""Pure tensor functions behind the boundary-aware mask loss.

All functions work on a batch of RoI masks ``Tensor[N, H, W]`` at once (no
Python loop over instances) and stay on the input's device.

Reading of the paper's edge loss
--------------------------------
The paper (CBNet, Sec. II.C.2, eq. (8)) builds its edge loss on the
Hausdorff distance ``d_H(A, B) = max(sup_a inf_b |a - b|, sup_b inf_a |a -
b|)`` between the predicted (A) and ground-truth (B) contours and writes
``L_edge = 1 - d_H``.  As written that is unbounded below and *rewards* a
larger distance, and ``d_H`` of thresholded masks has no useful gradient.
``d_H`` there can only be read as a bounded similarity ``1 - d~`` with ``d~``
a normalised, differentiable Hausdorff term, so ``L_edge = d~``.  We use the
distance-transform Hausdorff surrogate of Karimi & Salcudean (IEEE TMI 2019,
"HD_DT"), normalised by the RoI mask diagonal
``D = sqrt((H - 1)^2 + (W - 1)^2)`` (pixels)::

    L_edge = 1 / (2 |Omega|) * sum_x (p(x) - g(x))^2
             * ((d_g(x) / D)^alpha + (d_p(x) / D)^alpha)

with ``p`` the predicted probabilities, ``g`` the binary target, ``d_g`` /
``d_p`` the Euclidean distance (pixels, capped at ``D``) from each pixel to
the contour of the target / of the thresholded prediction ``p >= 0.5``
(constants, no gradient), ``|Omega| = H W``.  Every erroneous pixel is
weighted by how far it lies from the two contours; the pixels that realise
the Hausdorff distance get the largest weights, which is why Karimi &
Salcudean use it as a differentiable estimate of ``d_H``.  It is in
``[0, 1]``, independent of the RoI resolution, 0 if ``p == g``, and its
gradient is dense (unlike the max-min of ``d_H`` itself). The distance maps
may be computed on a grid coarsened by ``dist_stride`` (error at most
``(dist_stride - 1) sqrt(2)`` pixels; the loss uses 2 by default for speed).
:func:`hausdorff_distance` gives the exact normalised ``d_H`` of binary
masks, for evaluation and tests, from the same distance transforms.

Contours are inner boundaries ``M & ~erode_k(M)`` (``k x k`` erosion, zero
padding: outside the RoI is background), so a full mask's contour is the RoI
frame. Distance transforms are exact and vectorised: prefix max / min
scans along rows, then a min-plus pass along columns (``O(N H W H)``), with
a Python loop over rows / columns only, never over instances.

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
import torch.nn.functional as F
from torch import Tensor
from torch.autograd.function import once_differentiable

__all__ = [
    'mask_diagonal', 'mask_contour', 'dice_coefficient',
    'squared_distance_to_set', 'hausdorff_distance',
    'distance_weighted_error', 'boundary_loss', 'boundary_loss_autograd'
]


def _check_masks(name: str, masks: Tensor) -> None:
    if masks.dim() != 3:
        raise ValueError(f'{name} must be Tensor[N, H, W], got shape '
                         f'{tuple(masks.shape)}')


def _check_stride(stride: int) -> None:
    if int(stride) != stride or stride < 1:
        raise ValueError('stride (dist_stride) must be a positive integer, '
                         f'got {stride}')


def _check_kernel(kernel_size: int) -> None:
    if kernel_size < 3 or kernel_size % 2 == 0:
        raise ValueError('kernel_size (edge_kernel) must be an odd integer '
                         f'>= 3, got {kernel_size}')


def _check_edge_args(alpha: float, kernel_size: int, stride: int) -> None:
    if alpha <= 0:
        raise ValueError(f'alpha must be > 0, got {alpha}')
    _check_kernel(kernel_size)
    _check_stride(stride)


def _check_pair(name: str, masks: Tensor, other_name: str,
                other: Tensor) -> None:
    _check_masks(name, masks)
    if masks.shape != other.shape:
        raise ValueError(f'{name} {tuple(masks.shape)} and {other_name} '
                         f'{tuple(other.shape)} must have the same shape')


def mask_diagonal(h: int, w: int) -> float:
    """Diagonal of an ``h x w`` pixel grid, the distance normaliser ``D``.

    Args:
        h (int): Mask height (pixels).
        w (int): Mask width (pixels).

    Returns:
        float: ``sqrt((h - 1)^2 + (w - 1)^2)`` pixels, at least 1.
    """
    return math.sqrt(max((h - 1)**2 + (w - 1)**2, 1))


def mask_contour(masks: Tensor, kernel_size: int = 3) -> Tensor:
    """Inner contour of a batch of binary masks.

    ``M & ~erode(M)`` with a ``kernel_size`` square erosion and zero padding
    (outside the RoI is background), like
    ``mask & ~scipy.ndimage.binary_erosion(mask, np.ones((k, k)))``; a full
    mask's contour is the RoI frame.

    Args:
        masks (Tensor): ``Tensor[N, H, W]``; bool, or values ``> 0.5`` are
            foreground.
        kernel_size (int): Odd erosion window (pixels); the contour is
            ``(kernel_size - 1) / 2`` pixels thick. Defaults to 3.

    Returns:
        Tensor: bool ``Tensor[N, H, W]``.
    """
    _check_masks('masks', masks)
    _check_kernel(kernel_size)
    masks = masks if masks.dtype == torch.bool else masks > 0.5
    eroded = _erode_flat(masks.contiguous(), kernel_size // 2)
    return masks > eroded  # masks & ~eroded


def _erode_flat(masks: Tensor, rad: int) -> Tensor:
    """Square binary erosion (window ``2 rad + 1``, zero padding) of a
    contiguous bool ``Tensor[M, H, W]``.

    Separable: along W, then along H. Each pass combines shifted views of
    the *flattened* masks, so that every operand is one contiguous block
    (much faster than 2-D slices on CPU). Only the ``rad`` pixels next to
    each border see values wrapped in from the next row / instance (or
    left unset at the flat ends: the buffers need no zero fill), and the
    zero padding erodes exactly those: one AND with the interior clears
    them at the end.
    """
    num, h, w = masks.shape
    if min(h, w) <= 2 * rad:
        return torch.zeros_like(masks)
    out = masks
    for step in (1, w):
        src = out.reshape(-1)
        out = torch.empty_like(src)
        total, span = src.numel(), 2 * rad * step
        inner = out[rad * step:total - rad * step]
        torch.bitwise_and(src[:total - span], src[step:total - span + step],
                          out=inner)
        for i in range(2, 2 * rad + 1):
            torch.bitwise_and(inner, src[i * step:total - span + i * step],
                              out=inner)
    interior = torch.zeros(h, w, dtype=torch.bool, device=masks.device)
    interior[rad:h - rad, rad:w - rad] = True
    return out.view(num, h * w).bitwise_and_(interior.view(-1)).view(
        num, h, w)


def dice_coefficient(probs: Tensor,
                     targets: Tensor,
                     squared: bool = True) -> Tensor:
    """Per-instance Dice similarity coefficient (paper eq. (6)).

    ``DSC = 2 sum(S * S_gt) / sum(S^2 + S_gt^2)`` (``squared=True``, the
    paper's denominator as we read it, V-Net style) or
    ``2 sum(S * S_gt) / (sum(S) + sum(S_gt))``; both equal the set Dice on
    binary masks. Two empty masks have ``DSC = 1``.

    Args:
        probs (Tensor): Predicted probabilities, ``Tensor[N, H, W]``.
        targets (Tensor): Ground truth in ``[0, 1]``, ``Tensor[N, H, W]``.
        squared (bool): Use squared terms in the denominator.
            Defaults to True.

    Returns:
        Tensor: ``Tensor[N]`` in ``[0, 1]``.
    """
    _check_pair('probs', probs, 'targets', targets)
    inter = (probs * targets).flatten(1).sum(1)
    if squared:
        denom = (probs.square() + targets.square()).flatten(1).sum(1)
    else:
        denom = (probs + targets).flatten(1).sum(1)
    tiny = torch.finfo(probs.dtype).tiny
    dice = 2 * inter / denom.clamp_min(tiny)
    return torch.where(denom > 0, dice, torch.ones_like(dice))


def squared_distance_to_set(points: Tensor,
                            cap: Optional[float] = None,
                            stride: int = 1) -> Tensor:
    """Squared Euclidean distance transform to a set of pixels.

    ``out(x) = min(min_{a in set} |x - a|^2, cap^2)`` for each instance,
    like ``scipy.ndimage.distance_transform_edt(~points) ** 2``. A row scan
    (prefix max / min) gives the distance to the nearest set pixel in the
    same row; a min-plus pass over rows combines them (exact). No gradient.

    With ``stride > 1`` the transform runs on a grid coarsened by ``stride``
    (a coarse cell belongs to the set if any of its pixels does; distances
    between cell centres, scaled back to pixels, nearest upsampling): about
    ``stride^3`` times cheaper, off by at most ``(stride - 1) sqrt(2)``
    pixels. ``stride=1`` is exact.

    Args:
        points (Tensor): The set, ``Tensor[N, H, W]`` (bool, or values
            ``> 0.5`` are members).
        cap (float, optional): Upper bound (pixels), also the value where
            the set is empty. Defaults to the mask diagonal ``D``.
        stride (int): Coarsening factor. Defaults to 1.

    Returns:
        Tensor: Squared distances (pixels^2), float32, ``Tensor[N, H, W]``.
    """
    _check_masks('points', points)
    _check_stride(stride)
    _, h, w = points.shape
    if cap is None:
        cap = mask_diagonal(h, w)
    points = points > 0.5 if points.dtype != torch.bool else points
    with torch.no_grad():
        dist_sq = _coarse_squared_edt(points, stride).clamp_max_(cap * cap)
        return _upsample(dist_sq, stride, h, w)


def _coarsen(points: Tensor,
             stride: int,
             dtype: torch.dtype = torch.float32) -> Tensor:
    """Any-pool a set ``Tensor[M, H, W]`` (bool, or float 0 / 1) over
    ``stride x stride`` cells (zero padding to a multiple of ``stride``).

    Returns:
        Tensor: 0 / 1 ``Tensor[ceil(H / s), ceil(W / s), M]`` of ``dtype``,
        the cell-major layout that :func:`_squared_edt_hwm` works on.
    """
    if stride == 1:
        return _as_float(points.permute(1, 2, 0).contiguous(), dtype)
    combine = torch.bitwise_or if points.dtype == torch.bool else \
        torch.maximum
    num, h, w = points.shape
    hc, wc = -(-h // stride), -(-w // stride)
    if (hc * stride, wc * stride) != (h, w):
        padded = points.new_zeros(num, hc * stride, wc * stride)
        padded[:, :h, :w] = points
        points = padded
    h, w = hc * stride, wc * stride
    # any over the `stride` pixels right of / below each pixel, on the
    # flattened masks (contiguous operands: much faster on CPU than
    # strided 2-D slices); the wrapped values at the right / bottom ends
    # are never read below, only cells' top-left pixels are
    flat = points.contiguous().view(-1)
    total = flat.numel()
    for step in (1, w):
        span = (stride - 1) * step
        out = torch.empty_like(flat)
        combine(flat[:total - span], flat[step:total - span + step],
                out=out[:total - span])
        for i in range(2, stride):
            combine(out[:total - span], flat[i * step:total - span + i * step],
                    out=out[:total - span])
        flat = out
    cells = flat.view(num, h, w)[:, ::stride, ::stride].permute(1, 2, 0)
    if cells.dtype == torch.bool:
        cells = cells.view(torch.uint8)
    # one strided copy: cell-major layout and dtype conversion together
    return torch.empty(
        hc, wc, num, dtype=dtype, device=points.device).copy_(cells)


def _as_float(masks: Tensor, dtype=torch.float32) -> Tensor:
    """bool (or float) 0 / 1 -> ``dtype``; through uint8, several times
    faster than a direct bool cast on CPU."""
    if masks.dtype == torch.bool:
        masks = masks.view(torch.uint8)
    return masks.to(dtype)


def _edt_dtype(h: int, w: int) -> torch.dtype:
    """Arithmetic type of :func:`_squared_edt_hwm` on an ``h x w`` grid:
    int16 where its intermediate values (at most ``(h + 2 w - 1)^2 +
    (h - 1)^2``) fit (then the scans and min-plus steps move half the
    bytes of float32 and run about twice as fast on CPU; exact either
    way, all values are integers), else float32."""
    bound = (h + 2 * w - 1)**2 + (h - 1)**2
    return torch.int16 if bound < 2**15 else torch.float32


def _squared_edt_hwm(points: Tensor) -> Tensor:
    """Exact squared EDT of a 0 / 1 set in ``[H, W, M]`` layout.

    Works in ``points.dtype`` (float, or an integer type that holds the
    values, see :func:`_edt_dtype`). Empty sets give values ``>= (H +
    W)^2``. In this layout every slice below is a run of contiguous
    blocks. One prefix max scan over columns (dim 1), in place, finds the
    nearest set column on the left and, on a mirrored copy, on the right;
    then one min-plus step per row offset (dim 0), with one reused
    buffer, combines the rows.
    """
    h, w, num = points.shape
    far = h + w  # beyond any in-grid distance
    cols = torch.arange(w, device=points.device, dtype=points.dtype)
    # [H, W, 2, M]: the set, and the set mirrored along W; nearest set
    # column <= x: the running max of (x where set, else -far)
    nearest = torch.stack((points, points.flip(1)), dim=2)
    nearest.mul_((cols + far)[:, None, None]).sub_(far)
    steps = nearest.unbind(1)
    for x in range(1, w):
        torch.maximum(steps[x], steps[x - 1], out=steps[x])
    # column distance on each side (>= far where the row has no set cell)
    dist = torch.sub(cols[:, None, None], nearest, out=nearest)
    row_sq = torch.minimum(dist[:, :, 0], dist[:, :, 1].flip(1))
    row_sq.mul_(row_sq)  # square_ is a slow integer pow
    # out(r) = min_s row_sq(s) + (r - s)^2 over rows s (dim 0); row_sq
    # itself becomes row_sq + off^2 (two buffers, not three: the working
    # set matters more than the operation count)
    dist_sq = row_sq.clone()
    for off in range(1, h):
        row_sq.add_(2 * off - 1)
        torch.minimum(dist_sq[off:], row_sq[:h - off], out=dist_sq[off:])
        torch.minimum(dist_sq[:h - off], row_sq[off:], out=dist_sq[:h - off])
    return dist_sq


def _coarse_squared_edt(points: Tensor, stride: int) -> Tensor:
    """Squared EDT (pixels^2) of bool ``Tensor[N, H, W]`` on the grid
    coarsened by ``stride``: float32 ``Tensor[N, ceil(H / s), ceil(W /
    s)]``."""
    _, h, w = points.shape
    cells = _coarsen(points, stride,
                     _edt_dtype(-(-h // stride), -(-w // stride)))
    dist_sq = _squared_edt_hwm(cells).permute(2, 0, 1)
    return dist_sq.to(torch.float32,
                      memory_format=torch.contiguous_format).mul_(stride**2)


def _upsample(coarse: Tensor, stride: int, h: int, w: int) -> Tensor:
    """Nearest upsampling of ``Tensor[N, hc, wc]`` to ``Tensor[N, h, w]``."""
    if stride == 1:
        return coarse
    num, hc, wc = coarse.shape
    return coarse[:, :, None, :, None].expand(
        num, hc, stride, wc, stride).reshape(num, hc * stride,
                                             wc * stride)[:, :h, :w]


def hausdorff_distance(pred_masks: Tensor,
                       gt_masks: Tensor,
                       kernel_size: int = 3,
                       normalise: bool = True) -> Tensor:
    """Exact Hausdorff distance between the contours of binary masks.

    ``d_H = max(max_{a in A} d(a, B), max_{b in B} d(b, A))`` over the inner
    contours ``A`` / ``B`` (see :func:`mask_contour`), paper eq. (8). Two
    empty contours give 0, exactly one empty contour gives ``D`` (the cap).
    Not differentiable; for evaluation and tests.

    Args:
        pred_masks (Tensor): ``Tensor[N, H, W]``, values ``> 0.5`` are
            foreground.
        gt_masks (Tensor): ``Tensor[N, H, W]``, same convention.
        kernel_size (int): Contour erosion window. Defaults to 3.
        normalise (bool): Divide by the mask diagonal ``D`` so the result
            is in ``[0, 1]``. Defaults to True.

    Returns:
        Tensor: ``Tensor[N]``, pixels (or fraction of ``D``).
    """
    _check_pair('pred_masks', pred_masks, 'gt_masks', gt_masks)
    _, h, w = pred_masks.shape
    pred_edge = mask_contour(pred_masks, kernel_size)
    gt_edge = mask_contour(gt_masks, kernel_size)
    pred_to_gt = squared_distance_to_set(gt_edge) * pred_edge
    gt_to_pred = squared_distance_to_set(pred_edge) * gt_edge
    hd = torch.maximum(
        pred_to_gt.flatten(1).amax(1),
        gt_to_pred.flatten(1).amax(1)).sqrt()
    return hd / mask_diagonal(h, w) if normalise else hd


def distance_weighted_error(probs: Tensor,
                            targets: Tensor,
                            alpha: float = 2.0,
                            kernel_size: int = 3,
                            dist_stride: int = 1) -> Tensor:
    """Normalised distance-transform Hausdorff term (our ``L_edge``).

    ``1 / (2 H W) sum_x (p - g)^2 ((d_g / D)^alpha + (d_p / D)^alpha)``,
    Karimi & Salcudean's HD_DT normalised by the mask diagonal ``D``; see
    the module docstring for the definitions and why this reads the paper's
    ``L_edge``. The distance maps are constants; the gradient flows
    through ``(p - g)^2`` only.

    Args:
        probs (Tensor): Predicted probabilities, ``Tensor[N, H, W]``.
        targets (Tensor): Binary targets (``> 0.5`` is foreground),
            ``Tensor[N, H, W]``.
        alpha (float): Distance exponent (Karimi & Salcudean use 2).
            Defaults to 2.0.
        kernel_size (int): Contour erosion window. Defaults to 3.
        dist_stride (int): Grid coarsening of the distance maps (see
            :func:`squared_distance_to_set`); 1 is exact. Defaults to 1.

    Returns:
        Tensor: ``Tensor[N]`` in ``[0, 1]``.
    """
    _check_pair('probs', probs, 'targets', targets)
    _check_edge_args(alpha, kernel_size, dist_stride)
    num, h, w = probs.shape
    with torch.no_grad():
        # target and thresholded prediction in one batch
        masks = torch.empty(
            2 * num, h, w, dtype=torch.bool, device=probs.device)
        torch.gt(targets, 0.5, out=masks[:num])
        torch.ge(probs, 0.5, out=masks[num:])
        weight = _edge_weight_rows(masks, alpha, kernel_size, dist_stride,
                                   probs.dtype).permute(1, 0, 2)
        gt_bin = _as_float(masks[:num], probs.dtype)
    return _WeightedSquaredError.apply(probs, gt_bin, weight,
                                       dist_stride) / (2 * h * w)


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


class _WeightedSquaredError(torch.autograd.Function):
    """``sum_x weight(x) (probs(x) - target(x))^2`` per instance with an
    analytic backward ``2 weight (probs - target)``, the weights given per
    ``stride`` rows (``Tensor[N, ceil(H / stride), W]``, constants).

    Fused by hand because autograd would keep the difference, its square,
    the product and their gradients as separate full-size buffers, which
    on CPU cost more (allocation, page faults) than the arithmetic.
    ``target`` is an internal buffer and is overwritten.
    """

    @staticmethod
    def forward(ctx, probs: Tensor, target: Tensor, weight: Tensor,
                stride: int) -> Tensor:
        diff = torch.sub(probs, target, out=target)
        weighted = _mul_row_weights(diff, weight, stride)
        ctx.save_for_backward(weighted)
        return diff.mul_(weighted).flatten(1).sum(1)

    @staticmethod
    def backward(ctx, grad: Tensor):
        weighted, = ctx.saved_tensors
        grad_probs = None
        if ctx.needs_input_grad[0]:
            grad_probs = weighted * (2 * grad)[:, None, None]
        return grad_probs, None, None, None


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


def boundary_loss_autograd(logits: Tensor,
                           targets: Tensor,
                           lambda_shape: float = 1.0,
                           use_shape: bool = True,
                           lambda_edge: float = 1.0,
                           use_edge: bool = True,
                           alpha: float = 2.0,
                           kernel_size: int = 3,
                           dist_stride: int = 1,
                           index: Optional[Tensor] = None) -> Tensor:
    """:func:`boundary_loss` composed of differentiable tensor functions.

    MMDet's mask BCE (``binary_cross_entropy_with_logits``, pixel mean),
    :func:`dice_coefficient` and the edge term with its distance maps as
    constants, every differentiable step left to autograd: the readable
    form of the loss, the reference the fused function is tested against
    and the stock-ops baseline ``benchmark_kernels.py`` times it against
    (the loss itself always runs the fused function, measured faster on
    CPU and GPU). Same arguments and result as :func:`boundary_loss`.
    """
    if index is not None:
        logits = logits.index_select(0, index)
    _check_pair('logits', logits, 'targets', targets)
    _check_edge_args(alpha, kernel_size, dist_stride)
    if logits.dtype in (torch.float16, torch.bfloat16):
        logits = logits.float()
    targets = targets.to(logits.dtype)
    probs = logits.sigmoid()
    loss = F.binary_cross_entropy_with_logits(
        logits, targets, reduction='none').flatten(1).mean(1)
    if use_shape:
        loss = loss + 1 - dice_coefficient(probs, targets)
    loss = lambda_shape * loss
    if use_edge and len(targets):
        _, h, w = logits.shape
        with torch.no_grad():
            target_bin = targets > 0.5
            weight = sum(
                (squared_distance_to_set(
                    mask_contour(m, kernel_size), stride=dist_stride) /
                 mask_diagonal(h, w)**2).pow(alpha / 2)
                for m in (target_bin, probs >= 0.5)).to(logits.dtype)
        edge = ((probs - target_bin.to(logits.dtype))**2 *
                weight).flatten(1).mean(1) / 2
        loss = loss + lambda_edge * edge
    return loss


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
