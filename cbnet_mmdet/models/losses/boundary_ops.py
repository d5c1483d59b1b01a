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

The loss that trains runs the fused form of these functions,
:func:`cbnet_mmdet.models.losses.boundary_loss_fused.boundary_loss` (one
autograd function, measured faster on CPU and GPU); this module is the
readable definition it is tested against.
"""
import math
from typing import Optional

import torch
import torch.nn.functional as F
from torch import Tensor

__all__ = [
    'mask_diagonal', 'mask_contour', 'dice_coefficient',
    'squared_distance_to_set', 'hausdorff_distance',
    'distance_weighted_error', 'boundary_loss_autograd'
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
    _, h, w = probs.shape
    with torch.no_grad():
        target_bin = targets > 0.5
        weight = sum(
            (squared_distance_to_set(
                mask_contour(m, kernel_size), stride=dist_stride) /
             mask_diagonal(h, w)**2).pow(alpha / 2)
            for m in (target_bin, probs >= 0.5)).to(probs.dtype)
    return ((probs - target_bin.to(probs.dtype))**2 *
            weight).flatten(1).mean(1) / 2


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
    """The boundary-aware loss composed of differentiable tensor functions.

    MMDet's mask BCE (``binary_cross_entropy_with_logits``, pixel mean),
    :func:`dice_coefficient` and the edge term with its distance maps as
    constants (:func:`distance_weighted_error`), every differentiable step
    left to autograd: the readable form of the loss, the reference the
    fused :func:`~.boundary_loss_fused.boundary_loss` is tested against and
    the stock-ops baseline ``benchmark_kernels.py`` times it against (the
    loss itself always runs the fused function, measured faster on CPU and
    GPU). Same arguments and result.
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
        loss = loss + lambda_edge * distance_weighted_error(
            probs, targets, alpha, kernel_size, dist_stride)
    return loss
