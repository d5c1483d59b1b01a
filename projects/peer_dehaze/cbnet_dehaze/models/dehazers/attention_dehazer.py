"""YOLO-Vehicle-Pro's learned dehazing module (paper III-D)."""
from typing import Optional

from mmdet.registry import MODELS
from torch import Tensor, nn

from .attention_conv_block import (NEGATIVE_SLOPE, AttentionConvBlock,
                                   conv_lrelu)
from .base_dehazer import BaseDehazer


@MODELS.register_module()
class CBNetAttentionDehazer(BaseDehazer):
    """Residual dehazing network of attention-based convolution blocks.

    ``J = clamp(I + tail(blocks(head(I))), 0, 1)``: a 3x3 head convolution
    lifts the RGB image to ``channels`` features, ``num_blocks``
    :class:`AttentionConvBlock` s (shared layer, parallel CAB and
    (S)W-MSA branches summed, final convolution; Leaky ReLU 0.01) refine
    them, and a 3x3 tail convolution predicts a correction added to the
    hazy input (residual learning, paper III-D). The tail has no
    activation (fog removal needs negative corrections) and is
    zero-initialised, so an untrained dehazer is the identity; the other
    convolutions get Kaiming initialisation for Leaky ReLU (the paper
    adapts its initialisation to Leaky ReLU). The weights are initialised
    in the constructor: as part of a data preprocessor the module is not
    reached by ``init_weights()``.

    Works at full resolution on any H, W (the window attention pads).
    Cost grows linearly with pixels; see projects/peer_dehaze/README.md
    for CPU latency.

    Args:
        channels (int): Feature width. Defaults to 16 (small).
        num_blocks (int): Attention-conv blocks. Defaults to 2.
        num_heads (int): Attention heads (divides ``channels``).
            Defaults to 2.
        window_size (int): Attention window side in pixels. Defaults to 8.
        reduction (int): CAB bottleneck reduction. Defaults to 4.
        init_cfg (dict, optional): MMEngine init config (e.g.
            ``Pretrained``), applied by ``init_weights()``.
    """

    def __init__(self,
                 channels: int = 16,
                 num_blocks: int = 2,
                 num_heads: int = 2,
                 window_size: int = 8,
                 reduction: int = 4,
                 init_cfg: Optional[dict] = None) -> None:
        super().__init__(init_cfg=init_cfg)
        if min(channels, num_blocks, num_heads, window_size) < 1:
            raise ValueError(
                'CBNetAttentionDehazer: channels, num_blocks, num_heads and '
                'window_size must be positive')
        self.head = conv_lrelu(3, channels, 3)
        self.blocks = nn.Sequential(*[
            AttentionConvBlock(channels, num_heads, window_size, reduction)
            for _ in range(num_blocks)
        ])
        self.tail = nn.Conv2d(channels, 3, 3, padding=1)
        self.reset_parameters()

    def reset_parameters(self) -> None:
        """Kaiming (Leaky ReLU) convolutions, zero tail: identity map."""
        for m in self.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(
                    m.weight, a=NEGATIVE_SLOPE, nonlinearity='leaky_relu')
                nn.init.zeros_(m.bias)
        nn.init.zeros_(self.tail.weight)
        nn.init.zeros_(self.tail.bias)

    def features(self, img: Tensor) -> list:
        """Intermediate features (for PatchNCE).

        Args:
            img (Tensor[B, 3, H, W]): RGB in [0, 1].

        Returns:
            list[Tensor[B, C, H, W]]: head output, then each block's.
        """
        feats = [self.head(img)]
        for block in self.blocks:
            feats.append(block(feats[-1]))
        return feats

    def dehaze(self, img: Tensor) -> Tensor:
        """Tensor[B, 3, H, W] in [0, 1] -> input + predicted correction."""
        return img + self.tail(self.features(img)[-1])
