"""FCN mask head with an extra boundary (edge) output."""
from typing import List, Optional, Tuple, Union

import torch
import torch.nn as nn
from mmcv.cnn import build_conv_layer
from mmengine.config import ConfigDict
from mmdet.models.roi_heads.mask_heads import FCNMaskHead
from mmdet.models.task_modules.samplers import SamplingResult
from mmdet.registry import MODELS
from mmdet.utils import InstanceList, OptConfigType
from torch import Tensor

from ...losses.boundary_ops import mask_contour
from ...utils import use_channels_last


@MODELS.register_module()
class CBNetBoundaryMaskHead(FCNMaskHead):
    """Mask head predicting a mask and a boundary map from shared features.

    The convs and the upsampling of :class:`FCNMaskHead` are shared; a
    second 1x1 predictor (``conv_edge``) beside ``conv_logits`` gives
    class-agnostic boundary logits ``Tensor[N, 1, 2S, 2S]`` (``S`` the RoI
    feature size). Called as ``head(feats)`` it returns the mask logits only,
    so it also works in MMDet's single-output RoI heads;
    ``head(feats, return_edge=True)`` returns both.

    The edge output gets its own supervision: ``loss_edge`` (default a
    pixel BCE, MMDet's ``CrossEntropyLoss(use_mask=True)``) against the
    inner contour of the mask target (``edge_kernel`` x ``edge_kernel``
    erosion, the same contour the boundary-aware mask loss uses), logged as
    ``loss_edge``. ``loss_edge=None`` keeps the output unsupervised.

    At CPU inference the convolutions run in ``channels_last`` memory
    format (the RoI features are converted once, the logits converted
    back): oneDNN's 3x3 and transposed convolutions run forward much faster
    on NHWC than on NCHW tensors (100 RoIs of 256 x 14 x 14, one thread:
    830 -> 466 ms; same results up to float rounding). In training it
    gains nothing (forward + backward, 128 RoIs, 4 convs: 6.39 vs 6.37 s)
    and the neck's convolutions lose (see ``use_channels_last``), so both
    keep NCHW there. ``channels_last`` forces it on or off.

    Args:
        loss_edge (dict, optional): Loss config of the edge output, called
            like a mask loss ``(pred, target, label)``; None: no edge
            branch (no ``conv_edge``, ``with_edge`` False).
        edge_kernel (int): Odd erosion window (pixels) of the edge
            targets. Defaults to 3.
        channels_last (bool, optional): Run the convolutions on
            ``channels_last`` tensors; ``None`` (default) does so on CPU
            only.
        **kwargs: Arguments of :class:`FCNMaskHead` (``num_convs``,
            ``num_classes``, ``loss_mask``, ...).
    """

    def __init__(self,
                 loss_edge: OptConfigType = dict(
                     type='CrossEntropyLoss', use_mask=True, loss_weight=1.0),
                 edge_kernel: int = 3,
                 channels_last: Optional[bool] = None,
                 **kwargs) -> None:
        super().__init__(**kwargs)
        if edge_kernel < 3 or edge_kernel % 2 == 0:
            raise ValueError('edge_kernel must be an odd integer >= 3, got '
                             f'{edge_kernel}')
        self.edge_kernel = edge_kernel
        self.channels_last = channels_last
        self.loss_edge = None if loss_edge is None else MODELS.build(loss_edge)
        if self.loss_edge is not None:
            self.conv_edge = build_conv_layer(
                self.predictor_cfg, self.conv_logits.in_channels, 1, 1)

    @property
    def with_edge(self) -> bool:
        """bool: The head has a (supervised) edge output."""
        return self.loss_edge is not None

    def init_weights(self) -> None:
        """Initialise ``conv_edge`` like ``conv_logits``."""
        super().init_weights()
        if not self.with_edge:
            return
        nn.init.kaiming_normal_(
            self.conv_edge.weight, mode='fan_out', nonlinearity='relu')
        nn.init.constant_(self.conv_edge.bias, 0)

    def forward(self,
                x: Tensor,
                return_edge: bool = False
                ) -> Union[Tensor, Tuple[Tensor, Tensor]]:
        """Predict mask (and edge) logits.

        Args:
            x (Tensor): RoI features, ``Tensor[N, in_channels, S, S]``.
            return_edge (bool): Also return the edge logits.
                Defaults to False.

        Returns:
            Tensor | tuple[Tensor, Tensor]: Mask logits
            ``Tensor[N, C, 2S, 2S]`` (``C = 1`` if class-agnostic), and with
            ``return_edge`` the edge logits ``Tensor[N, 1, 2S, 2S]``.
        """
        if use_channels_last(self.channels_last, x):
            x = x.contiguous(memory_format=torch.channels_last)
        for conv in self.convs:
            x = conv(x)
        if self.upsample is not None:
            x = self.upsample(x)
            if self.upsample_method == 'deconv':
                x = self.relu(x)
        mask_preds = self.conv_logits(x).contiguous()
        if not return_edge:
            return mask_preds
        if not self.with_edge:
            raise ValueError(
                'CBNetBoundaryMaskHead: return_edge=True but the head has no '
                'edge branch (loss_edge=None)')
        return mask_preds, self.conv_edge(x).contiguous()

    def loss_and_target(self,
                        mask_preds: Tensor,
                        sampling_results: List[SamplingResult],
                        batch_gt_instances: InstanceList,
                        rcnn_train_cfg: ConfigDict,
                        edge_preds: Tensor = None) -> dict:
        """Mask loss as in :class:`FCNMaskHead`, plus the edge loss.

        Args:
            mask_preds (Tensor): ``Tensor[num_pos, C, H, W]`` logits.
            sampling_results (list[:obj:`SamplingResult`]): Per image.
            batch_gt_instances (list[:obj:`InstanceData`]): Per image, with
                ``masks``.
            rcnn_train_cfg (:obj:`ConfigDict`): ``train_cfg`` of the stage
                (``mask_size``).
            edge_preds (Tensor, optional): ``Tensor[num_pos, 1, H, W]`` edge
                logits; no ``loss_edge`` without them.

        Returns:
            dict: ``loss_mask`` (dict with ``loss_mask`` and, with edges and
            ``loss_edge`` set, ``loss_edge``) and ``mask_targets``
            ``Tensor[num_pos, H, W]``.
        """
        results = super().loss_and_target(
            mask_preds=mask_preds,
            sampling_results=sampling_results,
            batch_gt_instances=batch_gt_instances,
            rcnn_train_cfg=rcnn_train_cfg)
        if edge_preds is None or self.loss_edge is None:
            return results
        mask_targets = results['mask_targets']
        if edge_preds.size(0) == 0:
            loss_edge = edge_preds.sum() * 0.
        else:
            edge_targets = mask_contour(mask_targets, self.edge_kernel).to(
                edge_preds.dtype)
            loss_edge = self.loss_edge(
                edge_preds, edge_targets,
                torch.zeros(
                    edge_preds.size(0),
                    dtype=torch.long,
                    device=edge_preds.device))
        results['loss_mask']['loss_edge'] = loss_edge
        return results
