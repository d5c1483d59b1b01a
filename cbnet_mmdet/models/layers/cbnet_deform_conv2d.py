"""Deformable convolution as one gather and one matrix product."""
from typing import Optional, Tuple, Union

import torch
import torch.nn.functional as F
from mmcv.ops import deform_conv2d as mmcv_deform_conv2d
from mmdet.registry import MODELS
from torch import Tensor, nn
from torch.nn.modules.utils import _pair


def deform_conv2d(x: Tensor,
                  offset: Tensor,
                  weight: Tensor,
                  stride: Tuple[int, int] = (1, 1),
                  padding: Tuple[int, int] = (0, 0),
                  dilation: Tuple[int, int] = (1, 1)) -> Tensor:
    """mmcv's ``deform_conv2d`` (one group, one deformable group).

    Every output position ``p`` of tap ``k = i * kw + j`` reads the input at
    ``p * stride - padding + (i, j) * dilation + offset[2k: 2k + 2]``
    (``(dy, dx)``, mmcv's layout) by bilinear interpolation, with corners
    outside the map contributing zero. The four corners of all
    ``H_out * W_out * kh * kw`` samples are gathered and weighted in one
    ``F.embedding_bag`` over the channels-last rows of ``x`` (all channels
    of a pixel are contiguous, so each read is one cache-friendly row), and
    the taps are reduced with the weights in one matrix product. On CPU
    this is 2-4x faster than mmcv's kernel at inference and ~6x with the
    backward pass (docs/benchmarks.md); autograd
    gives the gradients of ``x``, ``offset`` and ``weight``.

    Args:
        x (Tensor): ``Tensor[N, C, H, W]``.
        offset (Tensor): ``Tensor[N, 2 * kh * kw, H_out, W_out]``.
        weight (Tensor): ``Tensor[O, C, kh, kw]``.
        stride, padding, dilation (tuple[int, int]): As ``nn.Conv2d``.

    Returns:
        Tensor: ``Tensor[N, O, H_out, W_out]``.
    """
    n, c, h, w = x.shape
    out_c, in_c, kh, kw = weight.shape
    taps = kh * kw
    h_out = max(
        (h + 2 * padding[0] - dilation[0] * (kh - 1) - 1) // stride[0] + 1, 0)
    w_out = max(
        (w + 2 * padding[1] - dilation[1] * (kw - 1) - 1) // stride[1] + 1, 0)
    if in_c != c:
        raise ValueError(f'deform_conv2d: input has {c} channels, the '
                         f'weight expects {in_c}')
    if offset.shape != (n, 2 * taps, h_out, w_out):
        raise ValueError(
            f'deform_conv2d: offset must be {(n, 2 * taps, h_out, w_out)} '
            f'for input {tuple(x.shape)} and a {kh}x{kw} kernel, got '
            f'{tuple(offset.shape)}')
    if n == 0 or h_out == 0 or w_out == 0:
        return x.new_zeros(n, out_c, h_out, w_out)
    dtype, device = offset.dtype, offset.device
    # sampling positions, [N, H_out, W_out, taps]
    tap_i = torch.arange(kh, device=device, dtype=dtype).repeat_interleave(kw)
    tap_j = torch.arange(kw, device=device, dtype=dtype).repeat(kh)
    rows = (torch.arange(h_out, device=device, dtype=dtype) * stride[0] -
            padding[0])
    cols = (torch.arange(w_out, device=device, dtype=dtype) * stride[1] -
            padding[1])
    off = offset.view(n, taps, 2, h_out, w_out).permute(0, 3, 4, 1, 2)
    py = rows.view(1, -1, 1, 1) + (tap_i * dilation[0]) + off[..., 0]
    px = cols.view(1, 1, -1, 1) + (tap_j * dilation[1]) + off[..., 1]
    y0, x0 = py.floor(), px.floor()
    ly, lx = py - y0, px - x0
    y0, x0 = y0.long(), x0.long()
    # one extra all-zero row for the corners outside the map
    zero_row = n * h * w
    base = (torch.arange(n, device=device) * (h * w)).view(n, 1, 1, 1)
    index, weights = [], []
    for dy, wy in ((0, 1 - ly), (1, ly)):
        for dx, wx in ((0, 1 - lx), (1, lx)):
            yy, xx = y0 + dy, x0 + dx
            inside = (yy >= 0) & (yy < h) & (xx >= 0) & (xx < w)
            index.append(torch.where(inside, base + yy * w + xx, zero_row))
            weights.append(wy * wx * inside)
    index = torch.stack(index, -1).view(-1, 4)
    weights = torch.stack(weights, -1).view(-1, 4).to(x.dtype)
    table = torch.cat([x.permute(0, 2, 3, 1).reshape(n * h * w, c),
                       x.new_zeros(1, c)])
    # [N * H_out * W_out * taps, C]: every sample, channels last
    samples = F.embedding_bag(
        index, table, per_sample_weights=weights, mode='sum')
    samples = samples.view(n * h_out * w_out, taps * c)
    out = samples @ weight.permute(0, 2, 3, 1).reshape(out_c, taps * c).t()
    return out.view(n, h_out, w_out, out_c).permute(0, 3, 1, 2).contiguous()


#: Where :func:`deform_conv2d` was measured faster than mmcv's kernel, so
#: that ``impl='auto'`` uses it: on CPU 2-4x at inference, ~6x with the
#: backward pass (docs/benchmarks.md). On an H100 (CUDA) mmcv's kernel
#: wins at inference, 2.2-3.8x at 512x1024 and 1024x2048, and the training
#: pass is a draw (gather 1.09x at 512x1024, 0.85x at 1024x2048):
#: ``tools/analysis_tools/benchmark_kernels.py --device cuda``,
#: docs/benchmarks.md "Custom kernels on each device".
GATHER_FASTER_ON = ('cpu', )


@MODELS.register_module()
class CBNetDeformConv2d(nn.Module):
    """Drop-in for ``mmcv.ops.DeformConv2d`` (no bias, one group, one
    deformable group), computed by :func:`deform_conv2d` on the devices
    where that was measured faster (``GATHER_FASTER_ON``: the CPU) and by
    mmcv's kernel elsewhere (``impl='auto'``); ``impl='gather'`` uses
    :func:`deform_conv2d` everywhere.

    Same ``weight`` parameter and state-dict key as mmcv's module, so a
    checkpoint of either loads into the other (``from_mmcv`` converts a
    built module, keeping its parameter).

    Args:
        in_channels (int): Input channels.
        out_channels (int): Output channels.
        kernel_size (int | tuple[int, int]): Kernel size.
        stride, padding, dilation (int | tuple[int, int]): As ``nn.Conv2d``.
        weight (nn.Parameter, optional): Use this ``Tensor[out_channels,
            in_channels, kh, kw]`` parameter (shared, not re-initialised,
            no random numbers drawn) instead of a new one.
        impl (str): ``'auto'`` (per device, above) or ``'gather'``.
            Defaults to ``'auto'``.
    """

    def __init__(self,
                 in_channels: int,
                 out_channels: int,
                 kernel_size: Union[int, Tuple[int, int]],
                 stride: Union[int, Tuple[int, int]] = 1,
                 padding: Union[int, Tuple[int, int]] = 0,
                 dilation: Union[int, Tuple[int, int]] = 1,
                 weight: Optional[nn.Parameter] = None,
                 impl: str = 'auto') -> None:
        super().__init__()
        if impl not in ('auto', 'gather'):
            raise ValueError("CBNetDeformConv2d: impl must be 'auto' or "
                             f"'gather', got {impl!r}")
        self.impl = impl
        self.in_channels, self.out_channels = in_channels, out_channels
        self.kernel_size = _pair(kernel_size)
        self.stride, self.padding = _pair(stride), _pair(padding)
        self.dilation = _pair(dilation)
        shape = (out_channels, in_channels, *self.kernel_size)
        if weight is None:
            weight = nn.Parameter(torch.empty(shape))
            nn.init.kaiming_uniform_(weight, a=5**0.5)
        elif tuple(weight.shape) != shape:
            raise ValueError(f'CBNetDeformConv2d: weight of shape '
                             f'{tuple(weight.shape)}, expected {shape}')
        self.weight = weight

    @classmethod
    def from_mmcv(cls, conv: nn.Module,
                  impl: str = 'auto') -> 'CBNetDeformConv2d':
        """The same convolution as an ``mmcv.ops.DeformConv2d``, sharing
        its ``weight`` parameter."""
        if conv.groups != 1 or conv.deform_groups != 1:
            raise ValueError(
                'CBNetDeformConv2d supports groups=1 and deform_groups=1, '
                f'got {conv.groups} and {conv.deform_groups}')
        if getattr(conv, 'bias', None) is not None:
            raise ValueError('CBNetDeformConv2d has no bias')
        # the same parameter, and no random numbers drawn: a model built
        # with either implementation gets the same initial weights
        return cls(conv.in_channels, conv.out_channels, conv.kernel_size,
                   conv.stride, conv.padding, conv.dilation, conv.weight,
                   impl)

    def forward(self, x: Tensor, offset: Tensor) -> Tensor:
        """``Tensor[N, C, H, W]``, offsets ``Tensor[N, 2*kh*kw, H', W']`` ->
        ``Tensor[N, out_channels, H', W']``."""
        if self.impl == 'auto' and x.device.type not in GATHER_FASTER_ON \
                and x.shape[0] > 0 and x.shape[2] >= self.kernel_size[0] \
                and x.shape[3] >= self.kernel_size[1]:
            # mmcv's kernel refuses maps smaller than the kernel (padding
            # not counted: the stride-64/128 levels of a small image) and
            # empty batches, which the gather kernel computes; it splits the
            # batch into chunks of im2col_step images, which must divide it
            n = x.shape[0]
            step = next(s for s in range(min(32, n), 0, -1) if n % s == 0)
            return mmcv_deform_conv2d(x, offset, self.weight, self.stride,
                                      self.padding, self.dilation, 1, 1,
                                      False, step)
        return deform_conv2d(x, offset, self.weight, self.stride,
                             self.padding, self.dilation)

    def extra_repr(self) -> str:
        return (f'{self.in_channels}, {self.out_channels}, kernel_size='
                f'{self.kernel_size}, stride={self.stride}, padding='
                f'{self.padding}, dilation={self.dilation}, '
                f'impl={self.impl!r}')
