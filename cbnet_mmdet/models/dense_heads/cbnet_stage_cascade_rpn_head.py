"""One stage of the CBNet Cascade RPN, its losses normalised by positives."""
from typing import Dict, List

import torch
from mmdet.models.dense_heads import StageCascadeRPNHead
from mmdet.models.utils import multi_apply
from mmdet.registry import MODELS
from mmdet.utils import InstanceList, OptInstanceList
from torch import Tensor

from ..layers import CBNetDeformConv2d


@MODELS.register_module()
class CBNetStageCascadeRPNHead(StageCascadeRPNHead):
    """MMDet's :class:`StageCascadeRPNHead`, losses averaged per positive.

    Without a sampler (every anchor of every level is trained, as the focal
    objectness of paper (3) wants), MMDet's stage head divides both losses
    by ``number of anchors / 200`` (a constant of guided anchoring). That
    makes the weight of one positive depend on the image size: about 30
    anchors' worth per image at 192x384 but 870 at 1024x2048 for a 4..64
    pyramid, so ``lambda_IoU``/``lambda_GIoU``/``lambda_obj`` mean different
    things at different input sizes, and the IoU loss (in [0, 1] per box)
    logs values above 1.

    With ``normalize_by_num_pos=True`` (default) the losses are divided by
    the number of positive anchors in the batch (at least 1 per image), the
    convention of focal-loss heads (RetinaNet, FCOS): the regression losses
    are then the mean ``1 - IoU`` / ``1 - GIoU`` over positives, and the
    loss per positive does not change when the same objects sit in a larger
    image. ``False`` keeps MMDet's factor.

    With a sampler in ``train_cfg`` the sampler's average factor is used
    either way, as in MMDet.

    The offset-mode adaptive convolution (stage 2) is a
    :class:`CBNetDeformConv2d` (the same function and parameter as mmcv's
    ``DeformConv2d``): with ``deform_impl='auto'`` (default) it runs the
    gather kernel on CPU, 2-4x faster than mmcv's there at inference and
    ~6x with the backward pass (the deformable convolution at the stride-4
    level was the largest part of the head's time), and mmcv's kernel on
    other devices, where it was measured faster (H100: 2.2-3.8x at
    inference); ``'gather'`` forces the gather kernel everywhere, ``'mmcv'``
    keeps mmcv's module.

    Args:
        normalize_by_num_pos (bool): Average the losses over positive
            anchors instead of ``anchors / 200``. Defaults to True.
        deform_impl (str): ``'auto'``, ``'gather'`` or ``'mmcv'``. Defaults
            to ``'auto'``.
        **kwargs: Arguments of :class:`StageCascadeRPNHead`.
    """

    def __init__(self, *args, normalize_by_num_pos: bool = True,
                 deform_impl: str = 'auto', **kwargs) -> None:
        if deform_impl not in ('auto', 'gather', 'mmcv'):
            raise ValueError(
                "CBNetStageCascadeRPNHead: deform_impl must be 'auto', "
                f"'gather' or 'mmcv', got {deform_impl!r}")
        self.normalize_by_num_pos = normalize_by_num_pos
        self.deform_impl = deform_impl
        super().__init__(*args, **kwargs)

    def _init_layers(self) -> None:
        """MMDet's layers; stage 2's deformable convolution swapped for
        :class:`CBNetDeformConv2d` (same parameter) unless ``'mmcv'``."""
        super()._init_layers()
        if self.deform_impl != 'mmcv' and \
                self.rpn_conv.adapt_type == 'offset':
            self.rpn_conv.conv = CBNetDeformConv2d.from_mmcv(
                self.rpn_conv.conv, self.deform_impl)

    def loss_by_feat(self,
                     anchor_list: List[List[Tensor]],
                     valid_flag_list: List[List[Tensor]],
                     cls_scores: List[Tensor],
                     bbox_preds: List[Tensor],
                     batch_gt_instances: InstanceList,
                     batch_img_metas: List[dict],
                     batch_gt_instances_ignore: OptInstanceList = None
                     ) -> Dict[str, Tensor]:
        """:meth:`StageCascadeRPNHead.loss_by_feat` with the average factor
        chosen here.

        The targets' ``avg_factor`` is the number of positives of the batch
        (MMDet's ``PseudoSampler`` counts at least one per image), or the
        sampler's factor with a sampler in ``train_cfg``; MMDet's head
        replaces the former with ``anchors / 200``, which this head does
        only with ``normalize_by_num_pos=False``. Same arguments and
        returns as MMDet's method (``loss_rpn_cls`` on a stage that
        classifies, ``loss_rpn_reg``).
        """
        featmap_sizes = [featmap.size()[-2:] for featmap in bbox_preds]
        (labels_list, label_weights_list, bbox_targets_list,
         bbox_weights_list, avg_factor, sampling_results_list) = \
            self.get_targets(
                anchor_list, valid_flag_list, featmap_sizes,
                batch_gt_instances, batch_img_metas,
                batch_gt_instances_ignore=batch_gt_instances_ignore,
                return_sampling_results=True)
        if not self.normalize_by_num_pos and \
                not sampling_results_list[0].avg_factor_with_neg:
            # MMDet's constant, from guided anchoring
            avg_factor = sum(label.numel() for label in labels_list) / 200.0
        # per image, per level -> per level, all images
        mlvl_anchors = [torch.cat(anchors) for anchors in zip(*anchor_list)]
        loss_cls, loss_reg = multi_apply(
            self.loss_by_feat_single, cls_scores, bbox_preds, mlvl_anchors,
            labels_list, label_weights_list, bbox_targets_list,
            bbox_weights_list, avg_factor=avg_factor)
        if self.with_cls:
            return dict(loss_rpn_cls=loss_cls, loss_rpn_reg=loss_reg)
        return dict(loss_rpn_reg=loss_reg)
