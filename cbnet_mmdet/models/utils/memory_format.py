"""Where the CBNet modules run their convolutions in ``channels_last``."""
from typing import Optional

import torch
from torch import Tensor


def use_channels_last(setting: Optional[bool], x: Tensor) -> bool:
    """Resolve a module's ``channels_last`` setting for its input ``x``.

    ``None`` means on CPU at inference only (no gradient recorded):
    oneDNN's 3x3 convolutions run forward faster on NHWC than on NCHW
    tensors there (docs/benchmarks.md), but their backward pass is slower
    (256 channels, one thread, forward + backward: 1.7 -> 4.4 s at 128x256,
    0.36 -> 0.62 s at 64x128; a MiT-B5 training step at 512x1024 spends
    3.5 s less in convolution backward with NCHW necks). On CUDA the fp32
    NCHW kernels are kept. ``True`` / ``False`` force it.

    Args:
        setting (bool, optional): The module's ``channels_last`` argument.
        x (Tensor): The module's input.

    Returns:
        bool: Whether to convert ``x`` to ``torch.channels_last``.
    """
    if setting is not None:
        return bool(setting)
    return x.device.type == 'cpu' and not torch.is_grad_enabled()
