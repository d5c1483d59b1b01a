"""Mask-logit distillation loss of CBNet-DD (paper section II.E, (11)).

The paper writes the loss as ``CE(sigma(y_t; T=tau), sigma(y_s; T=tau))``:
cross-entropy between the teacher's and the student's mask logits, both
scaled by a temperature ``T`` that is set dynamically to the "maximum
softmax probability" ``tau``. MMDetection's mask heads emit one *binary*
(sigmoid) logit ``z`` per pixel, so we read the formula as follows.

Note on the word "temperature": the logits are divided by ``T = tau``,
and a probability is at most 1, so ``T <= 1`` here (``[0.5, 1]`` below):
the scaling SHARPENS both distributions (``z / 0.5 = 2 z``), never softens
them as a distillation temperature ``T > 1`` would. It is strongest where
the teacher is least sure (``tau`` near 0.5) and vanishes for a confident
teacher (``tau`` near 1). This is the paper's formula taken literally; we
implement it as written and document the effect rather than invert it.

* Softmax of a binary logit. Every pixel is a two-class problem with class
  logits ``[0, z]``; its softmax at temperature ``T`` is
  ``[1 - sigmoid(z / T), sigmoid(z / T)]``.
* Maximum softmax probability. Per pixel it is
  ``max(sigmoid(z_t), 1 - sigmoid(z_t))`` of the *teacher* (its confidence,
  in ``[0.5, 1]``). ``tau`` is set per RoI to the **mean** of that value
  over the RoI's pixels. The mean, not the max, because the max over a
  28 x 28 mask saturates at ~1 for almost every RoI (any confident pixel
  suffices), which would make the temperature a constant 1. The mean
  tracks how sure the teacher is about the whole mask; it is detached.
  ``tau`` lies in ``[0.5, 1]``, so it never divides by zero.
* Cross-entropy that vanishes for identical inputs. ``CE(p, p)`` is the
  entropy of ``p``, not zero, so a student equal to its teacher would
  still be pushed to sharpen its masks. We subtract the teacher's entropy,
  i.e. use the KL divergence ``KL(p_t || p_s) = CE(p_t, p_s) - H(p_t)``,
  which has exactly the same gradient w.r.t. the student as the CE of the
  paper and is 0 if and only if the scaled distributions agree.
* Reduction. The KL is averaged over the pixels of each RoI (so the loss
  does not depend on the mask resolution), then reduced over RoIs with
  MMDetection's ``weight_reduce_loss`` (``weight``, ``avg_factor``,
  ``reduction``) and multiplied by ``loss_weight``. No ``T ** 2`` factor
  (the paper has none).

The teacher logits are detached inside the loss: gradients reach the
student only.
"""
from typing import Optional

import torch
import torch.nn as nn
import torch.nn.functional as F
from mmdet.models.losses.utils import weight_reduce_loss
from mmdet.registry import MODELS
from torch import Tensor


def binary_mask_temperature(teacher_logits: Tensor) -> Tensor:
    """Per-RoI temperature: mean over pixels of the teacher's max prob.

    Args:
        teacher_logits (Tensor): Binary mask logits, Tensor[N, ...] (e.g.
            Tensor[N, 28, 28]); everything after dim 0 is one RoI.

    Returns:
        Tensor: Tensor[N], values in [0.5, 1], detached.
    """
    prob = teacher_logits.detach().flatten(1).sigmoid()
    return torch.maximum(prob, 1 - prob).mean(dim=1)


def binary_mask_distill_loss(student_logits: Tensor,
                             teacher_logits: Tensor) -> Tensor:
    """Per-RoI KL between temperature-scaled binary mask distributions.

    The logits are divided by ``tau`` in ``[0.5, 1]``: a sharpening.

    Args:
        student_logits (Tensor): Tensor[N, ...] sigmoid logits of the student.
        teacher_logits (Tensor): Tensor[N, ...] sigmoid logits of the
            teacher, same shape; treated as constants.

    Returns:
        Tensor: Tensor[N], the KL divergence averaged over each RoI's pixels
        (nats per pixel).
    """
    teacher_logits = teacher_logits.detach()
    tau = binary_mask_temperature(teacher_logits)
    tau = tau.view(-1, *([1] * (teacher_logits.dim() - 1)))
    z_s = student_logits / tau
    z_t = teacher_logits / tau
    p_t = z_t.sigmoid()
    # KL(p_t || p_s) for Bernoulli distributions, in log-sigmoid form
    # (numerically stable for large |z|).
    kl = p_t * (F.logsigmoid(z_t) - F.logsigmoid(z_s)) + \
        (1 - p_t) * (F.logsigmoid(-z_t) - F.logsigmoid(-z_s))
    return kl.flatten(1).mean(dim=1)


@MODELS.register_module()
class CBNetDistillLoss(nn.Module):
    """Temperature-scaled mask-logit distillation (CBNet formula (11)).

    The temperature ``tau <= 1`` sharpens (see the module docstring).

    See the module docstring for the exact formula. Usable alone::

        loss = MODELS.build(dict(type='CBNetDistillLoss', loss_weight=1.0))
        loss(student_mask_logits, teacher_mask_logits)

    Args:
        loss_weight (float): Multiplier of the loss. Defaults to 1.0.
        reduction (str): ``'none'``, ``'mean'`` or ``'sum'`` over RoIs.
            Defaults to ``'mean'``.
    """

    def __init__(self,
                 loss_weight: float = 1.0,
                 reduction: str = 'mean') -> None:
        super().__init__()
        if reduction not in ('none', 'mean', 'sum'):
            raise ValueError(f'CBNetDistillLoss: reduction must be none, '
                             f'mean or sum, got {reduction!r}')
        self.loss_weight = loss_weight
        self.reduction = reduction

    def forward(self,
                pred: Tensor,
                target: Tensor,
                weight: Optional[Tensor] = None,
                avg_factor: Optional[float] = None,
                reduction_override: Optional[str] = None) -> Tensor:
        """Compute the loss.

        Args:
            pred (Tensor): Student mask logits, Tensor[N, 28, 28] (any
                Tensor[N, ...]).
            target (Tensor): Teacher mask logits of the same RoIs, same
                shape as ``pred``. Detached here.
            weight (Tensor, optional): Per-RoI weight, Tensor[N].
            avg_factor (float, optional): Divisor of the summed loss
                instead of N (``reduction='mean'`` only).
            reduction_override (str, optional): Overrides ``reduction``.

        Returns:
            Tensor: Scalar loss, or Tensor[N] with ``reduction='none'``.
        """
        if pred.shape != target.shape:
            raise ValueError(f'CBNetDistillLoss: student logits '
                             f'{tuple(pred.shape)} and teacher logits '
                             f'{tuple(target.shape)} differ in shape')
        reduction = reduction_override or self.reduction
        if reduction not in ('none', 'mean', 'sum'):
            raise ValueError(f'CBNetDistillLoss: bad reduction_override '
                             f'{reduction!r}')
        if pred.dim() < 2:
            raise ValueError('CBNetDistillLoss: expected Tensor[N, ...] mask '
                             f'logits, got shape {tuple(pred.shape)}')
        if pred.numel() == 0:
            # No RoI: keep the graph connected so DDP sees the parameters.
            empty = pred.sum() * 0
            return empty.expand(pred.shape[0]) if reduction == 'none' \
                else empty
        loss = binary_mask_distill_loss(pred, target)
        if weight is not None:
            weight = weight.float()
        loss = weight_reduce_loss(
            loss, weight, reduction=reduction, avg_factor=avg_factor)
        return self.loss_weight * loss
