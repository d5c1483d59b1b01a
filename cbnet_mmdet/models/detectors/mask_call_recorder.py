"""What a two-stage detector's last mask head saw in a loss call, read
with PyTorch forward hooks (CBNet-DD's student side)."""
from typing import List, NamedTuple, Optional, Tuple

import torch
import torch.nn as nn
from mmdet.models.roi_heads import CascadeRoIHead
from torch import Tensor


class MaskCall(NamedTuple):
    """One training call of a mask head.

    Attributes:
        rois (Tensor): ``Tensor[N, 5]`` (batch index, x1, y1, x2, y2 in
            input-image pixels): the positive RoIs the head ran on.
        labels (Tensor): ``Tensor[N]`` their ground-truth labels, as the
            head's mask loss received them (zeros for a class-agnostic
            head).
        mask_preds (Tensor): ``Tensor[N, C, h, w]`` the head's mask logits
            (with their graph).
    """
    rois: Tensor
    labels: Tensor
    mask_preds: Tensor


def last_mask_modules(roi_head: nn.Module) -> Tuple[nn.Module, nn.Module]:
    """The RoI extractor and mask head of a RoI head's last mask stage.

    ``StandardRoIHead`` and :class:`CBNetCascadeRoIHead` hold one of each;
    MMDet's ``CascadeRoIHead`` a ``ModuleList`` per stage (its last entry
    is taken). A shared extractor is the box extractor (of the last stage).

    Args:
        roi_head (nn.Module): The RoI head.

    Returns:
        tuple[nn.Module, nn.Module]: ``(mask_roi_extractor, mask_head)``.

    Raises:
        TypeError: the head has no such modules, or its mask head is not
            fed by its mask RoI extractor (a ``StandardRoIHead`` sharing
            the box extractor or with a shared head crops the box
            features instead, so its mask RoIs cannot be read).
    """
    head = getattr(roi_head, 'mask_head', None)
    extractor = getattr(roi_head, 'mask_roi_extractor', None)
    if isinstance(head, nn.ModuleList):
        head = head[-1]
    if isinstance(extractor, nn.ModuleList):
        extractor = extractor[-1]
    name = type(roi_head).__name__
    if not isinstance(head, nn.Module) or \
            not isinstance(extractor, nn.Module):
        raise TypeError(f'{name} has no mask_head and mask_roi_extractor '
                        f'modules: its mask logits and RoIs cannot be read')
    if not isinstance(roi_head, CascadeRoIHead) and (
            getattr(roi_head, 'share_roi_extractor', False)
            or getattr(roi_head, 'with_shared_head', False)):
        raise TypeError(
            f'{name} feeds its mask head the box features (shared RoI '
            f'extractor or shared head), not a mask RoI extractor of its '
            f'own: give it a mask_roi_extractor config')
    if not isinstance(getattr(head, 'loss_mask', None), nn.Module):
        raise TypeError(
            f'{type(head).__name__} has no loss_mask module (an FCNMaskHead '
            f'calls loss_mask(mask_preds, mask_targets, labels)): the '
            f'labels of its RoIs cannot be read')
    return extractor, head


class MaskCallRecorder:
    """Record the calls of a RoI head's last mask head during a loss call.

    Three forward hooks, removed on exit: on the mask RoI extractor (its
    RoIs and output), on the mask head (input and logits: the RoIs are
    those of the extractor call whose output the head took) and before
    the head's ``loss_mask`` (the labels it received beside those
    logits). It reads MMDet's RoI heads and :class:`CBNetCascadeRoIHead`
    from the outside, changing nothing they compute::

        with MaskCallRecorder(student.roi_head) as recorder:
            losses = student.roi_head.loss(x, proposals, data_samples)
        call = recorder.last_call()

    Args:
        roi_head (nn.Module): See :func:`last_mask_modules`.
    """

    def __init__(self, roi_head: nn.Module) -> None:
        self.extractor, self.mask_head = last_mask_modules(roi_head)
        self.calls: List[dict] = []
        self._extracted: Optional[Tuple[Tensor, Tensor]] = None
        self._handles: list = []

    def __enter__(self) -> 'MaskCallRecorder':
        self.calls, self._extracted = [], None
        self._handles = [
            self.extractor.register_forward_hook(
                self._on_extract, with_kwargs=True),
            self.mask_head.register_forward_hook(self._on_mask_head),
            self.mask_head.loss_mask.register_forward_pre_hook(
                self._on_loss),
        ]
        return self

    def __exit__(self, *exc_info) -> None:
        for handle in self._handles:
            handle.remove()
        self._handles, self._extracted = [], None

    def _on_extract(self, module, args, kwargs, output) -> None:
        rois = args[1] if len(args) > 1 else kwargs.get('rois')
        self._extracted = (rois, output)

    def _on_mask_head(self, module, args, output) -> None:
        feats = args[0] if args else None
        if self._extracted is None or feats is not self._extracted[1]:
            raise RuntimeError(
                f'{type(module).__name__} ran on features that are not its '
                f'RoI extractor\'s output: its RoIs cannot be read')
        logits = output[0] if isinstance(output, (tuple, list)) else output
        self.calls.append(
            dict(rois=self._extracted[0], mask_preds=logits, labels=None))

    def _on_loss(self, module, args) -> None:
        if len(args) < 3 or not self.calls:
            return
        call = self.calls[-1]
        if args[0] is call['mask_preds']:
            call['labels'] = args[2]

    def last_call(self) -> Optional[MaskCall]:
        """The last recorded call, or None when the head did not run.

        Raises:
            RuntimeError: the head ran on RoIs but its loss received no
                labels for those logits.
        """
        if not self.calls:
            return None
        call = self.calls[-1]
        labels = call['labels']
        if labels is None:
            if len(call['rois']) > 0:
                raise RuntimeError(
                    f'{type(self.mask_head).__name__}: its loss_mask was not '
                    f'called on the logits of its last call, so the labels '
                    f'of its {len(call["rois"])} RoIs are unknown')
            labels = torch.zeros(
                0, dtype=torch.long, device=call['rois'].device)
        return MaskCall(call['rois'], labels, call['mask_preds'])


def mask_logits_on(roi_head: nn.Module, feats: Tuple[Tensor],
                   rois: Tensor) -> Tensor:
    """The last mask stage's logits on given RoIs (the teacher's side).

    Args:
        roi_head (nn.Module): See :func:`last_mask_modules`.
        feats (tuple[Tensor]): Multi-level features ``Tensor[B, C, H, W]``.
        rois (Tensor): ``Tensor[N, 5]``.

    Returns:
        Tensor: ``Tensor[N, C, h, w]`` mask logits.
    """
    extractor, head = last_mask_modules(roi_head)
    logits = head(extractor(feats[:extractor.num_inputs], rois))
    return logits[0] if isinstance(logits, (tuple, list)) else logits
