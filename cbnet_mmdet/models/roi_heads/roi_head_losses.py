"""RoI-head training losses written out with the heads' own parts.

MMDet's ``StandardRoIHead.loss`` and ``CascadeRoIHead.loss`` keep the
sampled proposals and the mask logits to themselves. CBNet-DD
(:class:`~cbnet_mmdet.models.detectors.CBNetDistiller`) needs both: the
teacher's mask head runs on the RoIs the student's mask head was trained
on. As MMDet's SoftTeacher does for its pseudo-label losses, the steps are
called explicitly here (assign and sample, ``bbox_loss``, ``mask_loss``,
``refine_bboxes``), in MMDet's order and with MMDet's loss names and
weights, and the last mask call is returned beside the losses.
:class:`~cbnet_mmdet.models.roi_heads.CBNetCascadeRoIHead` trains through
the same cascade loop (mask head on the last stage, unweighted).
"""
from functools import partial
from typing import Callable, List, NamedTuple, Optional, Sequence, Tuple

import torch
from mmdet.models.roi_heads import CascadeRoIHead, StandardRoIHead
from mmdet.models.task_modules.samplers import SamplingResult
from mmdet.models.utils import unpack_gt_instances
from mmdet.structures import SampleList
from mmdet.utils import InstanceList
from torch import Tensor


class MaskLossRecord(NamedTuple):
    """What a head's last ``mask_loss`` call saw and returned.

    Attributes:
        stage (int, optional): The cascade stage, None for a single-stage
            head (``StandardRoIHead``).
        sampling_results (list[:obj:`SamplingResult`]): The samples the
            mask head was trained on (its RoIs: their ``pos_priors``).
        mask_results (dict): ``mask_loss``'s return: ``mask_preds`` logits
            ``Tensor[n, C, h, w]``, ``mask_targets``, ``loss_mask``.
    """
    stage: Optional[int]
    sampling_results: List[SamplingResult]
    mask_results: dict


def sample_proposals(assigner, sampler, x: Tuple[Tensor],
                     results_list: InstanceList,
                     batch_gt_instances: InstanceList,
                     batch_gt_instances_ignore: InstanceList
                     ) -> List[SamplingResult]:
    """Assign and sample each image's proposals, as MMDet's RoI heads do
    (the proposals' ``bboxes`` become ``priors``)."""
    sampling_results = []
    for i, results in enumerate(results_list):
        results.priors = results.pop('bboxes')
        assign_result = assigner.assign(results, batch_gt_instances[i],
                                        batch_gt_instances_ignore[i])
        sampling_results.append(
            sampler.sample(assign_result, results, batch_gt_instances[i],
                           feats=[lvl[i][None] for lvl in x]))
    return sampling_results


def standard_roi_losses(head: StandardRoIHead, x: Tuple[Tensor],
                        rpn_results_list: InstanceList,
                        batch_data_samples: SampleList
                        ) -> Tuple[dict, Optional[MaskLossRecord]]:
    """:meth:`StandardRoIHead.loss`, step by step, and its mask call.

    Returns:
        tuple: The losses (MMDet's names) and the :class:`MaskLossRecord`
        (None without a mask head).
    """
    assert len(rpn_results_list) == len(batch_data_samples)
    batch_gt_instances, batch_gt_instances_ignore, _ = \
        unpack_gt_instances(batch_data_samples)
    sampling_results = sample_proposals(
        head.bbox_assigner, head.bbox_sampler, x, rpn_results_list,
        batch_gt_instances, batch_gt_instances_ignore)
    losses = dict()
    bbox_feats = None
    if head.with_bbox:
        bbox_results = head.bbox_loss(x, sampling_results)
        losses.update(bbox_results['loss_bbox'])
        bbox_feats = bbox_results['bbox_feats']
    record = None
    if head.with_mask:
        mask_results = head.mask_loss(x, sampling_results, bbox_feats,
                                      batch_gt_instances)
        losses.update(mask_results['loss_mask'])
        record = MaskLossRecord(None, sampling_results, mask_results)
    return losses, record


def cascade_roi_losses(head: CascadeRoIHead,
                       x: Tuple[Tensor],
                       rpn_results_list: InstanceList,
                       batch_data_samples: SampleList,
                       mask_stages: Optional[Sequence[int]] = None,
                       weight_mask_losses: bool = True
                       ) -> Tuple[dict, Optional[MaskLossRecord]]:
    """:meth:`CascadeRoIHead.loss`, step by step, and its last mask call.

    Each stage assigns and samples its proposals, adds ``s{i}.*`` box
    losses scaled by ``stage_loss_weights[i]`` (accuracies unscaled), runs
    the mask head if the stage is one of ``mask_stages``, and refines the
    boxes for the next stage (stopping when none is left).

    Args:
        head (:obj:`CascadeRoIHead`): The head whose parts run.
        x (tuple[Tensor]): Multi-level features ``Tensor[B, C, H, W]``.
        rpn_results_list (list[:obj:`InstanceData`]): Proposals.
        batch_data_samples (list[:obj:`DetDataSample`]): Annotations.
        mask_stages (Sequence[int], optional): Stages that train the mask
            head; None: every stage (MMDet's cascade).
        weight_mask_losses (bool): Scale the mask losses by the stage
            weight too (MMDet's cascade), or add them at the weight their
            loss configs set (:class:`CBNetCascadeRoIHead`).

    Returns:
        tuple: The losses and the last :class:`MaskLossRecord` (None
        without a mask head).
    """
    assert len(rpn_results_list) == len(batch_data_samples)
    batch_gt_instances, batch_gt_instances_ignore, batch_img_metas = \
        unpack_gt_instances(batch_data_samples)
    if mask_stages is None:
        mask_stages = range(head.num_stages)
    losses = dict()
    record = None
    results_list = rpn_results_list
    for stage in range(head.num_stages):
        head.current_stage = stage
        weight = head.stage_loss_weights[stage]
        sampling_results = sample_proposals(
            head.bbox_assigner[stage], head.bbox_sampler[stage], x,
            results_list, batch_gt_instances, batch_gt_instances_ignore)
        bbox_results = head.bbox_loss(stage, x, sampling_results)
        for name, value in bbox_results['loss_bbox'].items():
            losses[f's{stage}.{name}'] = (
                value * weight if 'loss' in name else value)
        if head.with_mask and stage in mask_stages:
            mask_results = head.mask_loss(stage, x, sampling_results,
                                          batch_gt_instances)
            mask_weight = weight if weight_mask_losses else 1.0
            for name, value in mask_results['loss_mask'].items():
                losses[f's{stage}.{name}'] = (
                    value * mask_weight if 'loss' in name else value)
            record = MaskLossRecord(stage, sampling_results, mask_results)
        if stage == head.num_stages - 1:
            break
        with torch.no_grad():
            results_list = head.bbox_head[stage].refine_bboxes(
                sampling_results, bbox_results, batch_img_metas)
        if results_list is None:  # no proposal left
            break
    return losses, record


def roi_losses_with_mask_record(head, x: Tuple[Tensor],
                                rpn_results_list: InstanceList,
                                batch_data_samples: SampleList
                                ) -> Tuple[dict, Optional[MaskLossRecord]]:
    """A head's training losses (identical to its ``loss``) and its last
    mask call.

    Heads that define ``loss_with_mask_record`` (CBNet's cascade) answer
    themselves; MMDet's ``CascadeRoIHead`` and ``StandardRoIHead`` (and
    subclasses that do not override ``loss``) run through
    :func:`cascade_roi_losses` / :func:`standard_roi_losses`.

    Raises:
        TypeError: For another kind of RoI head, or one that overrides
            ``loss`` (its losses would not be reproduced).
    """
    losses_of = require_mask_record_losses(head)
    return losses_of(x, rpn_results_list, batch_data_samples)


def require_mask_record_losses(head) -> Callable:
    """:func:`mask_record_losses_of`, or a ``TypeError`` naming the head
    when it cannot be reproduced (for a check at build time too)."""
    losses_of = mask_record_losses_of(head)
    if losses_of is None:
        raise TypeError(
            f'{type(head).__name__} is not a StandardRoIHead or '
            f'CascadeRoIHead with their loss, and has no '
            f'loss_with_mask_record: its mask logits and RoIs cannot be read')
    return losses_of


def mask_record_losses_of(head) -> Optional[Callable]:
    """``f(x, rpn_results_list, batch_data_samples)`` giving ``head``'s
    losses and :class:`MaskLossRecord`, or None for a head it cannot
    reproduce (see :func:`roi_losses_with_mask_record`)."""
    if hasattr(head, 'loss_with_mask_record'):
        return head.loss_with_mask_record
    for base, losses_of in ((CascadeRoIHead, cascade_roi_losses),
                            (StandardRoIHead, standard_roi_losses)):
        if isinstance(head, base) and type(head).loss is base.loss:
            return partial(losses_of, head)
    return None
