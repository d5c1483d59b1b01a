"""PatchGAN discriminator for the unpaired dehazing objective."""
from mmdet.registry import MODELS
from torch import Tensor, nn

from .attention_conv_block import NEGATIVE_SLOPE


@MODELS.register_module()
class CBNetPatchDiscriminator(nn.Module):
    """PatchGAN (Isola et al. 2017), as CUT / UCL-Dehaze use it.

    ``num_layers`` stride-2 4x4 convolutions (doubling the width from
    ``channels``, capped at 8x), one stride-1 4x4 convolution and a
    1-channel 4x4 output: one real/fake logit per overlapping patch.
    Instance normalisation after all but the first convolution, Leaky
    ReLU 0.2 (the PatchGAN slope; the dehazer itself uses 0.01).

    Args:
        channels (int): Width of the first layer. Defaults to 32.
        num_layers (int): Stride-2 layers. Defaults to 3.
    """

    def __init__(self, channels: int = 32, num_layers: int = 3) -> None:
        super().__init__()
        slope = 20 * NEGATIVE_SLOPE  # 0.2
        layers = [nn.Conv2d(3, channels, 4, 2, 1), nn.LeakyReLU(slope, True)]
        width = channels
        for i in range(1, num_layers + 1):
            out = channels * min(2**i, 8)
            stride = 2 if i < num_layers else 1
            layers += [
                nn.Conv2d(width, out, 4, stride, 1),
                nn.InstanceNorm2d(out),
                nn.LeakyReLU(slope, True)
            ]
            width = out
        layers.append(nn.Conv2d(width, 1, 4, 1, 1))
        self.net = nn.Sequential(*layers)

    def forward(self, img: Tensor) -> Tensor:
        """Tensor[B, 3, H, W] in [0, 1] -> logits Tensor[B, 1, H', W']."""
        return self.net(img * 2 - 1)
