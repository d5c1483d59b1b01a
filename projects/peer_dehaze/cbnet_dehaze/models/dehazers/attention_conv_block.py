"""The attention-based convolution block of YOLO-Vehicle-Pro's dehazer.

Paper III-D1 (Fig. 4): a shared feature layer feeds two parallel branches,
a channel-attention branch (CAB) and a (shifted-)window multi-head
self-attention branch ((S)W-MSA), whose outputs are summed and passed
through a final convolution. III-D2: Leaky ReLU (slope 0.01) after the
convolutions. The window attention is MMDetection's Swin ``ShiftWindowMSA``.
"""
from mmdet.models.backbones.swin import ShiftWindowMSA
from torch import Tensor, nn

#: Negative slope of the Leaky ReLUs (paper III-D2, formula 14).
NEGATIVE_SLOPE = 0.01


def conv_lrelu(in_channels: int, out_channels: int,
               kernel_size: int) -> nn.Sequential:
    """``kernel_size`` convolution (same padding) + Leaky ReLU 0.01."""
    return nn.Sequential(
        nn.Conv2d(in_channels, out_channels, kernel_size,
                  padding=kernel_size // 2),
        nn.LeakyReLU(NEGATIVE_SLOPE, inplace=True))


class ChannelAttentionBranch(nn.Module):
    """CAB: convolutions, then sigmoid channel weights times its input.

    Two 3x3 convolutions refine the features; global average pooling and a
    1x1 bottleneck (``channels // reduction``) give one weight per channel
    (sigmoid), multiplied into the branch's input.

    Args:
        channels (int): Feature channels C.
        reduction (int): Bottleneck reduction of the weight MLP.
    """

    def __init__(self, channels: int, reduction: int = 4) -> None:
        super().__init__()
        hidden = max(1, channels // reduction)
        self.convs = nn.Sequential(
            conv_lrelu(channels, channels, 3),
            conv_lrelu(channels, channels, 3))
        self.weights = nn.Sequential(
            nn.AdaptiveAvgPool2d(1), conv_lrelu(channels, hidden, 1),
            nn.Conv2d(hidden, channels, 1), nn.Sigmoid())

    def forward(self, x: Tensor) -> Tensor:
        """Tensor[B, C, H, W] -> Tensor[B, C, H, W]."""
        return x * self.weights(self.convs(x))


class WindowAttentionBranch(nn.Module):
    """(S)W-MSA: window and shifted-window attention in parallel, summed.

    The paper's branch "processes the input through two parallel feature
    transformation modules, then adds the results"; we read the two as
    the regular-window (W-MSA) and the shifted-window (SW-MSA) attention of
    Swin, each after a LayerNorm, then a 1x1 convolution + Leaky ReLU.
    ``ShiftWindowMSA`` pads the map to whole windows, so any H, W works.

    Args:
        channels (int): Feature channels C (divisible by ``num_heads``).
        num_heads (int): Attention heads.
        window_size (int): Window side in pixels.
    """

    def __init__(self, channels: int, num_heads: int,
                 window_size: int) -> None:
        super().__init__()
        if channels % num_heads:
            raise ValueError(f'channels ({channels}) must be divisible by '
                             f'num_heads ({num_heads})')
        self.norm = nn.LayerNorm(channels)
        self.window = ShiftWindowMSA(
            channels, num_heads, window_size, shift_size=0)
        self.shifted = ShiftWindowMSA(
            channels, num_heads, window_size, shift_size=window_size // 2)
        self.proj = conv_lrelu(channels, channels, 1)

    def forward(self, x: Tensor) -> Tensor:
        """Tensor[B, C, H, W] -> Tensor[B, C, H, W]."""
        b, c, h, w = x.shape
        tokens = self.norm(x.flatten(2).transpose(1, 2))  # [B, HW, C]
        out = self.window(tokens, (h, w)) + self.shifted(tokens, (h, w))
        return self.proj(out.transpose(1, 2).reshape(b, c, h, w))


class AttentionConvBlock(nn.Module):
    """Shared layer -> (CAB + (S)W-MSA) -> conv, with a residual.

    Args:
        channels (int): Feature channels C.
        num_heads (int): Heads of the window attention.
        window_size (int): Window side of the window attention, pixels.
        reduction (int): Channel reduction inside the CAB weights.
    """

    def __init__(self, channels: int, num_heads: int, window_size: int,
                 reduction: int = 4) -> None:
        super().__init__()
        self.shared = conv_lrelu(channels, channels, 3)
        self.cab = ChannelAttentionBranch(channels, reduction)
        self.swmsa = WindowAttentionBranch(channels, num_heads, window_size)
        self.fuse = conv_lrelu(channels, channels, 3)

    def forward(self, x: Tensor) -> Tensor:
        """Tensor[B, C, H, W] -> Tensor[B, C, H, W]."""
        shared = self.shared(x)
        return x + self.fuse(self.cab(shared) + self.swmsa(shared))
