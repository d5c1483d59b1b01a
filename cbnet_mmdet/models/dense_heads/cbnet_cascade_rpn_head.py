"""The paper's two-stage Cascade RPN (CRPN, paper Sec. II.B)."""
import copy
from typing import List, Optional, Sequence, Union

from mmdet.models.dense_heads import CascadeRPNHead
from mmdet.registry import MODELS
from mmdet.utils import ConfigType, OptConfigType, OptMultiConfig
from mmengine.config import ConfigDict

from ..utils import RefuseMisfitMixin


# Stage 1 (anchor refinement) assigns by the anchor-centre region of each
# ground truth, without sampling; stage 2 (proposal refinement) by IoU with
# the stage-1 boxes. Stage 2 keeps every anchor (no sampler): the sigmoid
# focal loss down-weights the many easy negatives, which is why the paper
# uses it ("we generate more proposals in the prior stage"). Its assigner
# has an ignore band, RetinaNet's reading of a focal objective: IoU >= 0.5
# positive, < 0.4 negative, in between ignored (MMDet's Cascade RPN uses
# 0.7/0.7 with a sampler; without one, every near miss at IoU 0.4-0.7 would
# be a full-weight negative). Each GT keeps its best box if IoU >= 0.3.
DEFAULT_TRAIN_CFG = (
    dict(
        assigner=dict(
            type='RegionAssigner', center_ratio=0.2, ignore_ratio=0.5),
        allowed_border=-1,
        pos_weight=-1,
        debug=False),
    dict(
        assigner=dict(
            type='MaxIoUAssigner',
            pos_iou_thr=0.5,
            neg_iou_thr=0.4,
            min_pos_iou=0.3,
            ignore_iof_thr=-1),
        allowed_border=-1,
        pos_weight=-1,
        debug=False),
)


@MODELS.register_module()
class CBNetCascadeRPNHead(RefuseMisfitMixin, CascadeRPNHead):
    """Cascade RPN with the CBNet training objective (paper (2), (3)).

    Two ``StageCascadeRPNHead`` stages (Vu et al. 2019) on a pyramid:

    - stage 1: one square anchor per location, adaptive convolution in
      dilation mode (uniform anchors), class-agnostic box regression on
      decoded boxes with the IoU loss ``1 - IoU`` (``lambda_IoU = 10``);
      its boxes become the anchors of stage 2 (detached, as in Cascade RPN).
    - stage 2: adaptive convolution in offset mode: a deformable
      convolution (``mmcv.ops.DeformConv2d``) whose 3x3 sampling grid is
      laid over each stage-1 box; objectness with the sigmoid focal loss
      (``lambda_obj = 1``) and box regression with the GIoU loss
      (``lambda_GIoU = 10``) on decoded boxes.

    The head keeps MMDet's ``loss``, ``loss_and_predict`` and ``predict``,
    so it replaces ``RPNHead`` in any two-stage detector (Faster/Mask/
    Cascade R-CNN) or serves the ``RPN`` detector. In a stock Faster R-CNN
    config::

        model = dict(
            rpn_head=dict(_delete_=True, type='CBNetCascadeRPNHead'),
            train_cfg=dict(rpn=None))  # or a list of two per-stage dicts

    ``train_cfg.rpn=None`` selects the per-stage defaults below (the only
    place they are written); the detector's ``train_cfg.rpn_proposal`` /
    ``test_cfg.rpn`` set ``k`` as ``max_per_img`` (1000 in MMDet's Faster
    R-CNN).

    Loss normalisation: both stages are :class:`CBNetStageCascadeRPNHead`,
    which averages each loss over the positive anchors of the batch (the
    focal-loss convention), so a positive weighs the same at every input
    size. MMDet's stage head divides by ``number of anchors / 200`` when
    nothing is sampled, which changes the weight of a positive with the
    image size (``normalize_by_num_pos=False`` restores it).

    Args:
        num_classes (int): Must be 1 (class-agnostic). Defaults to 1.
        in_channels (int): Channels of every input level. Defaults to 256.
        feat_channels (int): Channels of the adaptive convolutions.
            Defaults to 256.
        strides (Sequence[int]): Stride of each input level (pixels).
            Defaults to (4, 8, 16, 32, 64).
        anchor_scale (int): Anchor side in units of the level stride.
            Defaults to 8.
        dilation (int): Dilation of stage 1's adaptive convolution.
            Defaults to 3.
        target_stds (Sequence[Sequence[float]]): ``DeltaXYWHBBoxCoder``
            standard deviations of stage 1 and stage 2.
        loss_iou (dict): Stage-1 regression loss; ``loss_weight`` is
            ``lambda_IoU``. Defaults to linear ``IoULoss``, weight 10.
        loss_obj (dict): Stage-2 objectness loss; ``loss_weight`` is
            ``lambda_obj``. Defaults to sigmoid ``FocalLoss`` (gamma 2,
            alpha 0.25), weight 1.
        loss_giou (dict): Stage-2 regression loss; ``loss_weight`` is
            ``lambda_GIoU``. Defaults to ``GIoULoss``, weight 10.
        obj_prior_prob (float): Initial objectness probability of stage 2
            (its classifier bias is set to ``-log((1 - p) / p)``, as for
            focal-loss heads, by ``init_weights()``). Defaults to 0.01.
        normalize_by_num_pos (bool): Average the losses over positive
            anchors (True) or over ``anchors / 200`` as MMDet's stage head
            does without a sampler. Defaults to True.
        deform_impl (str): Stage 2's deformable convolution: ``'auto'``
            (:class:`CBNetDeformConv2d`'s gather kernel on CPU, where it is
            2-4x faster, mmcv's kernel on other devices, where mmcv's was
            measured faster), ``'gather'`` (the gather kernel everywhere)
            or ``'mmcv'`` (``mmcv.ops.DeformConv2d``); the same function and
            weights. Defaults to ``'auto'``.
        train_cfg (list[dict], optional): One training config per stage
            (assigner, optional sampler, ``allowed_border``, ``pos_weight``).
            None uses ``DEFAULT_TRAIN_CFG``.
        test_cfg (dict, optional): Proposal post-processing: ``nms_pre``
            (boxes per level before NMS), ``max_per_img`` (k), ``nms``,
            ``min_bbox_size``. A detector passes its ``test_cfg.rpn`` (and
            ``train_cfg.rpn_proposal`` in training), as for every MMDet RPN
            head: the proposal settings live in the config alone
            (``configs/_base_/models/cbnet_mit-b5_nasfpn_crpn_cascade.py``:
            the paper's k = 1000 in training, 300 at test). None: the head
            trains, but proposing without a ``proposal_cfg`` raises.
        init_cfg (dict or list[dict], optional): Initialisation config.
            Defaults to None (each stage initialises its own layers).
    """

    def __init__(self,
                 num_classes: int = 1,
                 in_channels: int = 256,
                 feat_channels: int = 256,
                 strides: Sequence[int] = (4, 8, 16, 32, 64),
                 anchor_scale: int = 8,
                 dilation: int = 3,
                 target_stds: Sequence[Sequence[float]] = (
                     (0.1, 0.1, 0.5, 0.5), (0.05, 0.05, 0.1, 0.1)),
                 loss_iou: ConfigType = dict(
                     type='IoULoss', mode='linear', loss_weight=10.0),
                 loss_obj: ConfigType = dict(
                     type='FocalLoss',
                     use_sigmoid=True,
                     gamma=2.0,
                     alpha=0.25,
                     loss_weight=1.0),
                 loss_giou: ConfigType = dict(
                     type='GIoULoss', loss_weight=10.0),
                 obj_prior_prob: float = 0.01,
                 normalize_by_num_pos: bool = True,
                 deform_impl: str = 'auto',
                 train_cfg: Optional[Union[List[ConfigType],
                                           ConfigType]] = None,
                 test_cfg: OptConfigType = None,
                 init_cfg: OptMultiConfig = None) -> None:
        if len(target_stds) != 2:
            raise ValueError('CBNetCascadeRPNHead: target_stds needs one '
                             f'4-tuple per stage (2), got {target_stds}')
        if not loss_obj.get('use_sigmoid', False):
            raise ValueError(
                'CBNetCascadeRPNHead: loss_obj must be a sigmoid loss '
                "(use_sigmoid=True): the head has one objectness channel")
        train_cfg = self._check_train_cfg(train_cfg)
        if test_cfg is not None:
            test_cfg = ConfigDict(copy.deepcopy(test_cfg))
        anchor_generator = dict(
            type='AnchorGenerator',
            scales=[anchor_scale],
            ratios=[1.0],
            strides=list(strides))

        def stage(adapt_cfg: dict, stds: Sequence[float], **extra) -> dict:
            return dict(
                type='CBNetStageCascadeRPNHead',
                normalize_by_num_pos=normalize_by_num_pos,
                deform_impl=deform_impl,
                in_channels=in_channels,
                feat_channels=feat_channels,
                # Stage 2 needs the strides too: they place its offsets.
                anchor_generator=copy.deepcopy(anchor_generator),
                adapt_cfg=adapt_cfg,
                reg_decoded_bbox=True,
                bbox_coder=dict(
                    type='DeltaXYWHBBoxCoder',
                    target_means=(0., 0., 0., 0.),
                    target_stds=tuple(stds)),
                **copy.deepcopy(extra))

        stages = [
            stage(
                dict(type='dilation', dilation=dilation),
                target_stds[0],
                bridged_feature=True,
                with_cls=False,
                loss_bbox=loss_iou),
            stage(
                dict(type='offset'),
                target_stds[1],
                bridged_feature=False,
                with_cls=True,
                loss_cls=loss_obj,
                loss_bbox=loss_giou,
                # Focal loss is normalised by the (few) positives, so start
                # the objectness at the focal prior (RetinaNet's p = 0.01)
                # rather than p = 0.5: otherwise the thousands of negative
                # anchors give a loss of ~26 that swamps the gradient.
                init_cfg=dict(
                    type='Normal',
                    std=0.01,
                    override=[
                        dict(name='rpn_reg'),
                        dict(
                            type='Normal',
                            name='rpn_cls',
                            std=0.01,
                            bias_prob=obj_prior_prob)
                    ])),
        ]
        super().__init__(
            num_classes=num_classes,
            num_stages=len(stages),
            stages=stages,
            train_cfg=train_cfg,
            test_cfg=test_cfg,
            init_cfg=init_cfg)

    @staticmethod
    def _check_train_cfg(
        train_cfg: Optional[Union[List[ConfigType], ConfigType]]
    ) -> List[ConfigDict]:
        """Per-stage training configs, the defaults for None.

        Args:
            train_cfg (list[dict] or dict, optional): As given to the head
                (a detector passes its ``train_cfg.rpn``).

        Returns:
            list[ConfigDict]: One config per stage.
        """
        if train_cfg is None:
            train_cfg = DEFAULT_TRAIN_CFG
        if isinstance(train_cfg, dict):
            raise ValueError(
                'CBNetCascadeRPNHead: train_cfg (the detector\'s '
                '`train_cfg.rpn`) is a single dict, as for RPNHead; it must '
                'be a list with one dict per stage (2), or None for the '
                'paper\'s defaults, e.g. `train_cfg=dict(rpn=None)`')
        if len(train_cfg) != 2:
            raise ValueError(
                'CBNetCascadeRPNHead: train_cfg (`train_cfg.rpn`) needs one '
                f'dict per stage (2), got {len(train_cfg)}')
        return [ConfigDict(copy.deepcopy(cfg)) for cfg in train_cfg]

    def _check_proposal_cfg(self, cfg: OptConfigType) -> None:
        if cfg is None and self.test_cfg is None:
            raise ValueError(
                'CBNetCascadeRPNHead: no proposal settings: build it with '
                'test_cfg=dict(nms_pre=..., max_per_img=..., nms=..., '
                'min_bbox_size=...) (a detector passes its test_cfg.rpn) '
                'or pass proposal_cfg')

    def loss_and_predict(self, x, batch_data_samples,
                         proposal_cfg: OptConfigType = None):
        """MMDet's ``loss_and_predict``, after checking that proposal
        settings exist (``proposal_cfg`` or ``test_cfg``)."""
        self._check_proposal_cfg(proposal_cfg)
        return super().loss_and_predict(x, batch_data_samples,
                                        proposal_cfg=proposal_cfg)

    def predict(self, x, batch_data_samples, rescale: bool = False):
        """MMDet's ``predict``, after checking that ``test_cfg`` exists."""
        self._check_proposal_cfg(None)
        return super().predict(x, batch_data_samples, rescale=rescale)
