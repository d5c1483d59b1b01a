"""Where the CBNet modules run their convolutions in ``channels_last``."""
from typing import Optional

from torch import Tensor


def use_channels_last(setting: Optional[bool], x: Tensor) -> bool:
    """Resolve a module's ``channels_last`` setting for its input ``x``.

    ``None`` means on CPU only: oneDNN's convolutions are much faster on
    NHWC than on NCHW tensors there (docs/benchmarks.md), while on CUDA the
    fp32 NCHW kernels are kept. ``True`` / ``False`` force it.

    Args:
        setting (bool, optional): The module's ``channels_last`` argument.
        x (Tensor): The module's input.

    Returns:
        bool: Whether to convert ``x`` to ``torch.channels_last``.
    """
    return x.device.type == 'cpu' if setting is None else bool(setting)
