"""Boundary-aware mask loss of CBNet (paper Sec. II.C.2, eqs. (6)-(9)).

``L_bound = lambda_shape * L_shape + lambda_edge * L_edge`` per instance,
averaged over the instances of the batch:

* ``L_shape = BCE(S, S_gt) + (1 - DSC(S, S_gt))`` (eq. (7)); with
  ``use_shape=False`` only the BCE remains, i.e. MMDet's plain mask
  cross-entropy (the "CE only" row of the paper's Table 3).
* ``L_edge``: the paper's ``1 - d_H`` read as a bounded, resolution-
  normalised, differentiable Hausdorff term, the diagonal-normalised
  distance-transform Hausdorff loss of Karimi & Salcudean (2019); the exact
  formula and the reasoning are in :mod:`.boundary_ops`.
"""
from typing import Optional, Tuple

import torch
import torch.nn as nn
from mmdet.models.losses.utils import weight_reduce_loss
from mmdet.registry import MODELS
from torch import Tensor

from .boundary_loss_fused import boundary_loss


@MODELS.register_module()
class CBNetBoundaryAwareLoss(nn.Module):
    """Boundary-aware mask loss ``L_bound``, usable as any head's loss_mask.

    Per instance ``i`` (``S_i = sigmoid(logits_i)``, ``G_i`` the target)::

        L_i = lambda_shape * (BCE(S_i, G_i) + use_shape * (1 - DSC(S_i, G_i)))
              + use_edge * lambda_edge * L_edge(S_i, G_i)

    with BCE the pixel mean, ``DSC = 2 sum(S G) / sum(S^2 + G^2)`` (paper
    eq. (6)) and ``L_edge = 1 / (2 H W) sum_x (S - G)^2 ((d_G / D)^alpha +
    (d_S / D)^alpha)``, where ``d_G`` / ``d_S`` are the distances (pixels)
    of each pixel to the contour of ``G`` / of ``S >= 0.5`` (computed on a
    grid coarsened by ``dist_stride``) and ``D`` the RoI mask diagonal;
    every term lies in ``[0, 1]`` except the BCE. The instance losses are
    reduced with MMDet's ``weight_reduce_loss`` and multiplied by
    ``loss_weight``. All instances are processed at once, by
    :func:`.boundary_loss_fused.boundary_loss` (one autograd function, forward
    and backward fused).

    The call signature matches ``CrossEntropyLoss(use_mask=True)``, so it is
    a drop-in ``loss_mask`` for ``FCNMaskHead`` and its subclasses. With
    ``use_shape=False, use_edge=False, lambda_shape=1`` it equals that loss.

    Args:
        use_shape (bool): Add the Dice part of ``L_shape``. Defaults to True.
        use_edge (bool): Add ``L_edge``. Defaults to True.
        lambda_shape (float): Weight of ``L_shape`` (paper's
            lambda_shape). Defaults to 1.0.
        lambda_edge (float): Weight of ``L_edge`` (paper's lambda_edge).
            Defaults to 1.0.
        alpha (float): Distance exponent of ``L_edge`` (Karimi & Salcudean
            use 2). Defaults to 2.0.
        edge_kernel (int): Odd erosion window (pixels) that defines the
            contours. Defaults to 3.
        dist_stride (int): Grid coarsening of the edge term's distance
            maps (the weights, not the error map): 1 is exact, 2 is about 8x
            cheaper and off by at most sqrt(2) pixels (see
            ``boundary_ops.squared_distance_to_set``). Defaults to 2; the
            cost against MMDet's mask BCE on CPU is measured by
            ``tools/analysis_tools/benchmark_mask_loss.py``.
        reduction (str): ``'none'``, ``'mean'`` or ``'sum'`` over
            instances. Defaults to ``'mean'``.
        loss_weight (float): Global multiplier. Defaults to 1.0.
    """

    def __init__(self,
                 use_shape: bool = True,
                 use_edge: bool = True,
                 lambda_shape: float = 1.0,
                 lambda_edge: float = 1.0,
                 alpha: float = 2.0,
                 edge_kernel: int = 3,
                 dist_stride: int = 2,
                 reduction: str = 'mean',
                 loss_weight: float = 1.0) -> None:
        super().__init__()
        if reduction not in ('none', 'mean', 'sum'):
            raise ValueError("reduction must be 'none', 'mean' or 'sum', got "
                             f'{reduction!r}')
        if edge_kernel < 3 or edge_kernel % 2 == 0:
            raise ValueError('edge_kernel must be an odd integer >= 3, got '
                             f'{edge_kernel}')
        if alpha <= 0:
            raise ValueError(f'alpha must be > 0, got {alpha}')
        if int(dist_stride) != dist_stride or dist_stride < 1:
            raise ValueError('dist_stride must be a positive integer, got '
                             f'{dist_stride}')
        self.use_shape = use_shape
        self.use_edge = use_edge
        self.lambda_shape = lambda_shape
        self.lambda_edge = lambda_edge
        self.alpha = alpha
        self.edge_kernel = edge_kernel
        self.dist_stride = int(dist_stride)
        self.reduction = reduction
        self.loss_weight = loss_weight

    @staticmethod
    def _select_class(pred: Tensor, target: Tensor,
                      label: Tensor) -> Tuple[Tensor, Optional[Tensor]]:
        """Check shapes and locate each RoI's class channel.

        Returns:
            tuple[Tensor, Tensor | None]: ``Tensor[N, H, W]`` logits of the
            labelled class, and None; or (``C > 1``) the ``Tensor[N * C,
            H, W]`` logits and the row of each RoI's class, which
            :func:`.boundary_loss_fused.boundary_loss` selects itself (a
            contiguous copy, and its gradient scattered directly).
        """
        if pred.dim() != 4:
            raise ValueError('pred must be Tensor[N, C, H, W] mask logits, '
                             f'got shape {tuple(pred.shape)}')
        num, channels, h, w = pred.shape
        if tuple(target.shape) != (num, h, w):
            raise ValueError(f'target must be Tensor[N, H, W] = {(num, h, w)} '
                             f'to match pred, got {tuple(target.shape)}')
        if channels == 1:  # class-agnostic masks
            return pred[:, 0], None
        if label is None or tuple(label.shape) != (num, ):
            got = None if label is None else tuple(label.shape)
            raise ValueError(f'label must be Tensor[N] = ({num},) class '
                             f'indices for a {channels}-class pred, got {got}')
        rows = torch.arange(
            0, num * channels, channels, device=pred.device) + label.long()
        return pred.flatten(0, 1), rows

    def instance_losses(self,
                        logits: Tensor,
                        target: Tensor,
                        index: Optional[Tensor] = None) -> Tensor:
        """Unweighted ``L_bound`` of each instance.

        Args:
            logits (Tensor): Mask logits, ``Tensor[N, H, W]``, or the rows
                ``index`` of ``logits`` are.
            target (Tensor): Targets in ``[0, 1]``, ``Tensor[N, H, W]``.
            index (Tensor, optional): ``Tensor[N]`` rows of ``logits``.

        Returns:
            Tensor: ``Tensor[N]``.
        """
        return boundary_loss(
            logits,
            target,
            index=index,
            lambda_shape=self.lambda_shape,
            use_shape=self.use_shape,
            lambda_edge=self.lambda_edge,
            use_edge=self.use_edge,
            alpha=self.alpha,
            kernel_size=self.edge_kernel,
            dist_stride=self.dist_stride)

    def forward(self,
                pred: Tensor,
                target: Tensor,
                label: Optional[Tensor] = None,
                weight: Optional[Tensor] = None,
                avg_factor: Optional[float] = None,
                reduction_override: Optional[str] = None,
                **kwargs) -> Tensor:
        """Compute the loss.

        Args:
            pred (Tensor): Mask logits, ``Tensor[N, C, H, W]`` (``C = 1`` for
                class-agnostic heads).
            target (Tensor): Binary mask targets, ``Tensor[N, H, W]``.
            label (Tensor, optional): Class index of each RoI, ``Tensor[N]``;
                needed when ``C > 1``.
            weight (Tensor, optional): Per-instance weight, ``Tensor[N]``.
            avg_factor (float, optional): Denominator of the mean instead
                of ``N``.
            reduction_override (str, optional): Overrides ``reduction``.

        Returns:
            Tensor: Scalar loss, or ``Tensor[N]`` with reduction ``'none'``.
        """
        if reduction_override not in (None, 'none', 'mean', 'sum'):
            raise ValueError('reduction_override must be None, "none", '
                             f'"mean" or "sum", got {reduction_override!r}')
        reduction = reduction_override or self.reduction
        logits, index = self._select_class(pred, target, label)
        if weight is not None and tuple(weight.shape) != (len(target), ):
            raise ValueError(f'weight must be Tensor[N] = ({len(target)},), '
                             f'got {tuple(weight.shape)}')
        if len(target) == 0 and reduction != 'none':
            # no positive RoI: a zero that keeps the graph connected
            return pred.sum() * 0.
        loss = weight_reduce_loss(
            self.instance_losses(logits, target, index),
            weight=None if weight is None else weight.to(logits.dtype),
            reduction=reduction,
            avg_factor=avg_factor)
        return self.loss_weight * loss
