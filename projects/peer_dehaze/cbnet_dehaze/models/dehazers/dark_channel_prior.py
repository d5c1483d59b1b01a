"""Dark channel prior dehazing (He, Sun, Tang, CVPR 2009 / TPAMI 2011)."""
import torch
from mmdet.registry import MODELS
from torch import Tensor

from cbnet_mmdet.utils.dark_channel import DarkChannelPrior
from cbnet_mmdet.utils.scattering import recover
from .base_dehazer import BaseDehazer


@MODELS.register_module()
class CBNetDarkChannelPrior(BaseDehazer, DarkChannelPrior):
    """Training-free dehazing with the dark channel prior.

    For the scattering model ``I = J t + A (1 - t)``, the estimates of
    :class:`~cbnet_mmdet.utils.dark_channel.DarkChannelPrior` (dark
    channel, atmospheric light ``A``, guided-filter-refined transmission
    ``t``), then ``J = (I - A) / max(t, t0) + A``
    (:func:`cbnet_mmdet.utils.scattering.recover`). Batched
    tensor code, CPU and CUDA, any B, H, W. There are no parameters.

    Args:
        **kwargs: ``patch_size`` (15), ``omega`` (0.95), ``t0`` (0.1),
            ``top_fraction`` (0.001), ``guided_radius`` (40),
            ``guided_eps`` (1e-3), ``min_atmosphere`` (0.05): see
            ``DarkChannelPrior``.
    """

    def __init__(self, **kwargs) -> None:
        BaseDehazer.__init__(self, init_cfg=None)
        DarkChannelPrior.__init__(self, **kwargs)

    def dehaze(self, img: Tensor) -> Tensor:
        """Recover ``J = (I - A) / t + A`` for Tensor[B, 3, H, W] in [0, 1].
        """
        with torch.no_grad():
            light = self.atmospheric_light(img, self.dark_channel(img))
        return recover(img, self.transmission(img, light), light)
