"""Cascade RoI head whose mask head runs on the last stage only."""
from typing import List, Tuple

import torch
from mmdet.models.roi_heads import CascadeRoIHead
from mmdet.models.task_modules.samplers import SamplingResult
from mmdet.models.utils import empty_instances
from mmdet.registry import MODELS
from mmdet.structures import SampleList
from mmdet.structures.bbox import bbox2roi
from mmdet.utils import ConfigType, InstanceList, OptConfigType
from torch import Tensor


@MODELS.register_module()
class CBNetCascadeRoIHead(CascadeRoIHead):
    """Cascade R-CNN box stages + one mask head on the last stage (CBNet).

    The box side is MMDet's :class:`CascadeRoIHead` unchanged: ``num_stages``
    bbox heads trained on proposals re-sampled with the IoU thresholds of
    each stage's ``train_cfg[i].assigner`` (paper: 0.5 / 0.7 / 0.9), stage
    losses scaled by ``stage_loss_weights``, box regression and
    classification losses from each bbox head's config (the paper's
    class-agnostic smooth-L1 regression is ``reg_class_agnostic=True``,
    ``loss_bbox=dict(type='SmoothL1Loss')``). Inference averages the stages'
    class scores and decodes the last stage's boxes, as MMDet does.

    Unlike MMDet's head, which builds one mask head per stage and averages
    their masks, ``mask_head`` is a single config (e.g.
    :class:`CBNetBoundaryMaskHead`): in training it runs on the positive RoIs
    sampled for the last stage and yields ``s{num_stages - 1}.loss_mask``
    (and ``.loss_edge``) at the weight its loss config sets; in inference
    it runs once on the final boxes.

    Training runs MMDet's cascade loop (:meth:`CascadeRoIHead.loss`)
    unchanged; :meth:`mask_loss`, which the loop calls on every stage, is
    the one override: it runs the mask head on the last stage only.

    Mask loss weight: MMDet's cascade multiplies every loss of stage ``i``
    by ``stage_loss_weights[i]``, mask losses included, so a mask head on
    the last stage alone would train at ``stage_loss_weights[-1]`` (0.25 in
    Cascade R-CNN) times its configured weight. The paper adds ``L_bound``
    to the total at weight 1 (eq. 10), so the stage weights scale the box
    stages only: :meth:`mask_loss` returns the mask losses divided by
    ``stage_loss_weights[-1]`` (which must be positive), and the logged
    ``s{num_stages - 1}.loss_mask`` equals the unscaled loss times the mask
    loss config's ``loss_weight``. For a mask head on every stage, scaled
    by the stage weights, use MMDet's ``CascadeRoIHead`` with a list of
    mask heads (``configs/demo/parts/*mask-per-stage*``).

    Args:
        num_stages (int): Number of box stages (3 in the paper).
        stage_loss_weights (list[float]): Loss weight of each stage.
        mask_roi_extractor (dict, optional): A single RoI extractor config
            for the mask head; None shares the last stage's box extractor.
        mask_head (dict, optional): A single mask head config.
        **kwargs: Other arguments of :class:`CascadeRoIHead`.
    """

    def init_mask_head(self, mask_roi_extractor: OptConfigType,
                       mask_head: ConfigType) -> None:
        """Build the single last-stage mask head and its RoI extractor.

        Args:
            mask_roi_extractor (dict, optional): RoI extractor config, or
                None to share ``bbox_roi_extractor[-1]``.
            mask_head (dict): Mask head config.
        """
        for name, cfg in (('mask_head', mask_head),
                          ('mask_roi_extractor', mask_roi_extractor)):
            if isinstance(cfg, (list, tuple)):
                raise TypeError(
                    f'CBNetCascadeRoIHead: {name} must be a single config '
                    'dict (the mask head runs on the last stage only), got '
                    f'a list of {len(cfg)}')
        self.mask_head = MODELS.build(mask_head)
        if mask_roi_extractor is not None:
            self.share_roi_extractor = False
            self.mask_roi_extractor = MODELS.build(mask_roi_extractor)
        else:
            self.share_roi_extractor = True
            self.mask_roi_extractor = self.bbox_roi_extractor[-1]

    @property
    def _mask_has_edge(self) -> bool:
        return getattr(self.mask_head, 'with_edge', False)

    def _check_mask_stage(self, stage: int) -> None:
        if stage not in (-1, self.num_stages - 1):
            raise ValueError(
                f'CBNetCascadeRoIHead has a mask head on the last stage only '
                f'(stage {self.num_stages - 1} or -1), got stage {stage}')

    def _mask_forward(self, stage: int, x: Tuple[Tensor],
                      rois: Tensor) -> dict:
        """Run the last-stage mask head on RoIs.

        Args:
            stage (int): ``num_stages - 1`` or ``-1`` (the only mask stage).
            x (tuple[Tensor]): Multi-level features ``Tensor[B, C, H, W]``.
            rois (Tensor): ``Tensor[n, 5]`` (batch index, x1, y1, x2, y2 in
                input-image pixels).

        Returns:
            dict: ``mask_preds`` logits ``Tensor[n, C, 28, 28]`` and, if the
            head has one, ``edge_preds`` logits ``Tensor[n, 1, 28, 28]``
            (for a 14x14 RoI feature size).
        """
        self._check_mask_stage(stage)
        extractor = self.mask_roi_extractor
        mask_feats = extractor(x[:extractor.num_inputs], rois)
        if self._mask_has_edge:
            mask_preds, edge_preds = self.mask_head(
                mask_feats, return_edge=True)
            return dict(mask_preds=mask_preds, edge_preds=edge_preds)
        return dict(mask_preds=self.mask_head(mask_feats))

    def mask_loss(self, stage: int, x: Tuple[Tensor],
                  sampling_results: List[SamplingResult],
                  batch_gt_instances: InstanceList) -> dict:
        """Mask forward and losses of a stage, as MMDet's cascade loop
        (:meth:`CascadeRoIHead.loss`, unchanged) calls it for every stage.

        A stage before the last has no mask head: nothing runs and no loss
        is returned. On the last stage the mask head runs on the positive
        RoIs and its losses are returned divided by
        ``stage_loss_weights[-1]``, which the loop multiplies every loss of
        the stage by: the total and the log carry them at the weight their
        loss configs set (see the class doc).

        Args:
            stage (int): The cascade stage, ``0 .. num_stages - 1`` (or
                ``-1``, the last).
            x (tuple[Tensor]): Multi-level features.
            sampling_results (list[:obj:`SamplingResult`]): Samples of this
                stage, per image.
            batch_gt_instances (list[:obj:`InstanceData`]): Per image, with
                ``masks``.

        Returns:
            dict: ``loss_mask`` (a dict of the mask head's losses, empty
            before the last stage) and, on the last stage, ``mask_preds``
            (and ``edge_preds``) and ``mask_targets``.

        Raises:
            ValueError: ``stage`` is not a stage of the head, or the last
                stage's loss weight is not positive (the mask losses could
                not be carried at their configured weight).
        """
        if not -self.num_stages <= stage < self.num_stages:
            raise ValueError(
                f'CBNetCascadeRoIHead has stages 0..{self.num_stages - 1}, '
                f'got stage {stage}')
        if stage % self.num_stages != self.num_stages - 1:
            return dict(loss_mask=dict())  # no mask head on this stage
        weight = self.stage_loss_weights[-1]
        if not weight > 0:
            raise ValueError(
                f'CBNetCascadeRoIHead: stage_loss_weights[-1] must be > 0 '
                f'(MMDet\'s cascade loop multiplies the mask losses of the '
                f'last stage by it, this head divides them by it), got '
                f'{weight}')
        pos_rois = bbox2roi([res.pos_priors for res in sampling_results])
        mask_results = self._mask_forward(stage, x, pos_rois)
        extra = dict(edge_preds=mask_results['edge_preds']) \
            if 'edge_preds' in mask_results else dict()
        mask_results.update(
            self.mask_head.loss_and_target(
                mask_preds=mask_results['mask_preds'],
                sampling_results=sampling_results,
                batch_gt_instances=batch_gt_instances,
                rcnn_train_cfg=self.train_cfg[stage],
                **extra))
        mask_results['loss_mask'] = {
            name: value / weight if 'loss' in name else value
            for name, value in mask_results['loss_mask'].items()
        }
        return mask_results

    def predict_mask(self,
                     x: Tuple[Tensor],
                     batch_img_metas: List[dict],
                     results_list: InstanceList,
                     rescale: bool = False) -> InstanceList:
        """Masks of the final boxes from the last-stage mask head.

        Args:
            x (tuple[Tensor]): Multi-level features.
            batch_img_metas (list[dict]): Image meta information.
            results_list (list[:obj:`InstanceData`]): Detections per image
                (``bboxes``, ``labels``, ``scores``).
            rescale (bool): Return masks in the original image size.

        Returns:
            list[:obj:`InstanceData`]: ``results_list`` with ``masks``
            (bool ``Tensor[n, H, W]``).
        """
        mask_rois = bbox2roi([res.bboxes for res in results_list])
        if mask_rois.shape[0] == 0:
            return empty_instances(
                batch_img_metas,
                mask_rois.device,
                task_type='mask',
                instance_results=results_list,
                mask_thr_binary=self.test_cfg.mask_thr_binary)
        mask_preds = self._mask_forward(-1, x, mask_rois)['mask_preds']
        mask_preds = mask_preds.split([len(res) for res in results_list], 0)
        return self.mask_head.predict_by_feat(
            mask_preds=mask_preds,
            results_list=results_list,
            batch_img_metas=batch_img_metas,
            rcnn_test_cfg=self.test_cfg,
            rescale=rescale)

    def forward(self, x: Tuple[Tensor], rpn_results_list: InstanceList,
                batch_data_samples: SampleList) -> tuple:
        """Tensor-mode forward (no post-processing).

        Args:
            x (tuple[Tensor]): Multi-level features.
            rpn_results_list (list[:obj:`InstanceData`]): Proposals.
            batch_data_samples (list[:obj:`DetDataSample`]): Meta info.

        Returns:
            tuple: Per-image averaged class scores, last-stage box deltas
            and, with a mask head, per-image last-stage mask probabilities
            ``Tensor[n_i, C, 28, 28]``.
        """
        batch_img_metas = [s.metainfo for s in batch_data_samples]
        proposals = [res.bboxes for res in rpn_results_list]
        num_proposals_per_img = tuple(len(p) for p in proposals)
        rois, cls_scores, bbox_preds = self._refine_roi(
            x, bbox2roi(proposals), batch_img_metas, num_proposals_per_img)
        results = (cls_scores, bbox_preds)
        if self.with_mask:
            mask_preds = self._mask_forward(-1, x,
                                            torch.cat(rois))['mask_preds']
            results = results + (tuple(
                mask_preds.sigmoid().split(num_proposals_per_img, 0)), )
        return results
