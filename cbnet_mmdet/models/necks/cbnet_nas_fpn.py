"""NAS-FPN adapter neck between the MiT backbone and the CBNet heads."""
from typing import List, Optional, Sequence, Tuple

import torch
import torch.nn.functional as F
from mmcv.cnn import ConvModule
from mmdet.models.necks import NASFPN
from mmdet.registry import MODELS
from mmdet.utils import MultiConfig, OptConfigType
from torch import Tensor

from ..utils import RefuseMisfitMixin, use_channels_last

# The searched NAS-FPN cell graph (Ghiasi et al. 2019, as in MMDet's
# ``NASFPN``) merges exactly five consecutive pyramid levels.
NUM_GRAPH_LEVELS = 5


@MODELS.register_module()
class CBNetNASFPN(RefuseMisfitMixin, NASFPN):
    """NAS-FPN adapter for the Mix Transformer stages (paper Sec. II.A).

    The four MiT stage outputs (strides 4/8/16/32, different widths) are
    projected to ``out_channels`` by 1x1 convolutions, extra coarser levels
    are made by a 1x1 convolution and a stride-2 max pooling, and
    ``stack_times`` NAS-FPN stacks of MMCV merging cells (``SumCell``,
    ``GlobalPoolingCell``) fuse the five finest levels. The cell graph is
    MMDet's ``NASFPN`` graph, relabelled so that its P3..P7 are the levels of
    strides ``4 * 2**start_level`` .. ``64 * 2**start_level``: the graph only
    depends on relative strides, so it is unchanged.

    Size rule: a level of stride ``s`` on an ``H x W`` image is
    ``ceil(H / s) x ceil(W / s)``. MiT's overlapping patch embeddings
    (k7 s4 p3, then k3 s2 p1) produce exactly these sizes for any ``H, W``;
    the extra levels pool with ``ceil_mode=True`` so they keep the rule
    (MMDet's ``NASFPN`` floors, which gives a 0-sized level for a 1-pixel
    stride-32 map). Every merging cell resizes its inputs to the size of its
    output level (interpolation with ``upsample_mode`` to go up, zero-padded
    max pooling to go down), so odd sizes are handled.

    Levels beyond the five of the cell graph (``num_outs > 5``) are made from
    the coarsest graph output by further stride-2 max pooling (ceil mode).

    ``fine_path='light'`` (a speed setting, see docs/benchmarks.md) moves the
    cell graph one level coarser, onto strides ``8 * 2**start_level`` ..
    ``128 * 2**start_level`` (MMDet's NAS-FPN starts at stride 8 too), and
    makes the finest output as FPN does: a 1x1 lateral convolution of the
    finest backbone map plus the graph's finest output upsampled, then one
    3x3 convolution. The outputs keep their strides and sizes; the graph's
    stride-128 level feeds the cells only. At 512x1024 the cells at stride 4
    are about two thirds of the default neck's multiply-adds.

    Args:
        in_channels (Sequence[int]): Channels of each backbone output, e.g.
            ``[32, 64, 160, 256]`` (MiT-B0) or ``[64, 128, 320, 512]``
            (MiT-B1..B5).
        out_channels (int): Channels of every output level. Defaults to 256.
        num_outs (int): Number of output levels, at least 5. Defaults to 5.
        stack_times (int): Number of stacked NAS-FPN cell graphs.
            Defaults to 7 (NAS-FPN's 7 @ 256 setting).
        start_level (int): Index of the first backbone output used; the
            finest output level has that output's stride. Defaults to 0
            (stride 4 for MiT).
        end_level (int): Index of the last backbone output used, -1 for the
            last one. Defaults to -1.
        norm_cfg (dict, optional): Normalisation of every convolution.
            Defaults to None.
        upsample_mode (str): ``'nearest'`` or ``'bilinear'``: how merging
            cells enlarge a coarser input. Defaults to ``'nearest'``.
        fine_path (str): ``'cells'`` (default; our first reading of the
            paper: the cell graph spans the five finest levels) or
            ``'light'`` (the graph starts one level coarser; the finest
            level is an FPN-style lateral + top-down sum and one 3x3
            convolution; the paper configs' setting).
        channels_last (bool, optional): Run the cells on ``channels_last``
            tensors (outputs are returned contiguous NCHW, as the RoI and
            deformable-convolution ops downstream expect). ``None``
            (default): at CPU inference only, where oneDNN's 3x3
            convolutions run forward faster on NHWC tensors (MiT-B5 widths,
            256x512 input, one thread: 854 -> 631 ms; same results up to
            rounding) but backward much slower (``use_channels_last``).
        init_cfg (dict or list[dict], optional): Initialisation config.
            Defaults to Caffe2Xavier on every ``Conv2d``.
    """

    def __init__(
        self,
        in_channels: Sequence[int],
        out_channels: int = 256,
        num_outs: int = 5,
        stack_times: int = 7,
        start_level: int = 0,
        end_level: int = -1,
        norm_cfg: OptConfigType = None,
        upsample_mode: str = 'nearest',
        fine_path: str = 'cells',
        channels_last: Optional[bool] = None,
        init_cfg: MultiConfig = dict(type='Caffe2Xavier', layer='Conv2d')
    ) -> None:
        in_channels = list(in_channels)
        num_ins = len(in_channels)
        if num_outs < NUM_GRAPH_LEVELS:
            raise ValueError(
                f'CBNetNASFPN: num_outs={num_outs}, but the NAS-FPN cell '
                f'graph needs {NUM_GRAPH_LEVELS} levels')
        if not 0 <= start_level < num_ins:
            raise ValueError(
                f'CBNetNASFPN: start_level={start_level} is not an index '
                f'of in_channels (length {num_ins})')
        if upsample_mode not in ('nearest', 'bilinear'):
            raise ValueError(
                "CBNetNASFPN: upsample_mode must be 'nearest' or "
                f"'bilinear', got {upsample_mode!r}")
        if fine_path not in ('cells', 'light'):
            raise ValueError(
                "CBNetNASFPN: fine_path must be 'cells' or 'light', got "
                f'{fine_path!r}')
        light = fine_path == 'light'
        if light and (start_level + 1 >= num_ins or end_level != -1):
            raise ValueError(
                "CBNetNASFPN: fine_path='light' needs a backbone level "
                'above start_level for the cell graph and end_level=-1, got '
                f'start_level={start_level}, end_level={end_level} with '
                f'{num_ins} inputs')
        used = (num_ins if end_level == -1 else end_level + 1) - start_level
        if used > NUM_GRAPH_LEVELS:
            raise ValueError(
                f'CBNetNASFPN: {used} backbone levels are used, more than '
                f'the {NUM_GRAPH_LEVELS} of the NAS-FPN cell graph; raise '
                'start_level or set end_level')
        if end_level not in (-1, num_ins - 1) and used != NUM_GRAPH_LEVELS:
            raise ValueError(
                f'CBNetNASFPN: end_level={end_level} stops before the last '
                'backbone level, so no extra level is made and exactly '
                f'{NUM_GRAPH_LEVELS} backbone levels must be used, got {used}')
        super().__init__(
            in_channels=in_channels,
            out_channels=out_channels,
            num_outs=NUM_GRAPH_LEVELS,
            stack_times=stack_times,
            # the graph's finest level is one coarser on the light path
            start_level=start_level + int(light),
            end_level=end_level,
            norm_cfg=norm_cfg,
            init_cfg=init_cfg)
        self.num_outs = num_outs
        self.fine_path = fine_path
        self.fine_level = start_level
        if light:
            self.fine_lateral = ConvModule(
                in_channels[start_level],
                out_channels,
                1,
                norm_cfg=norm_cfg,
                act_cfg=None)
            self.fine_conv = ConvModule(
                out_channels,
                out_channels,
                3,
                padding=1,
                norm_cfg=norm_cfg,
                act_cfg=None)
        self.upsample_mode = upsample_mode
        self.channels_last = channels_last
        # Keep the ceil(H / s) size rule on the extra (pooled) levels.
        for downsample in self.extra_downsamples:
            downsample[-1].ceil_mode = True
        for stage in self.fpn_stages:
            for cell in stage.values():
                cell.upsample_mode = upsample_mode

    def forward(self, inputs: Sequence[Tensor]) -> Tuple[Tensor, ...]:
        """Build the pyramid.

        Args:
            inputs (Sequence[Tensor]): Backbone outputs, the i-th of shape
                ``Tensor[B, in_channels[i], H_i, W_i]``.

        Returns:
            tuple[Tensor]: ``num_outs`` maps of shape
            ``Tensor[B, out_channels, ceil(H / s), ceil(W / s)]``, strides
            ``s`` doubling from the stride of ``inputs[start_level]``.
        """
        if len(inputs) != len(self.in_channels):
            raise ValueError(
                f'CBNetNASFPN: expected {len(self.in_channels)} input maps '
                f'(in_channels={self.in_channels}), got {len(inputs)}')
        got = [x.shape[1] for x in inputs]
        if got != self.in_channels:
            raise ValueError(
                f'CBNetNASFPN: input channels {got} do not match '
                f'in_channels={self.in_channels}')
        if use_channels_last(self.channels_last, inputs[0]):
            inputs = [
                x.contiguous(memory_format=torch.channels_last)
                for x in inputs
            ]
        outs: List[Tensor] = list(super().forward(inputs))
        if self.fine_path == 'light':
            fine = self.fine_lateral(inputs[self.fine_level])
            fine = fine + F.interpolate(
                outs[0], size=fine.shape[-2:], mode=self.upsample_mode)
            # the stride-128 graph level is not an output
            outs = [self.fine_conv(fine)] + outs[:NUM_GRAPH_LEVELS - 1]
        for _ in range(self.num_outs - NUM_GRAPH_LEVELS):
            outs.append(F.max_pool2d(outs[-1], 2, stride=2, ceil_mode=True))
        return tuple(x.contiguous() for x in outs)
