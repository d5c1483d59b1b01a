"""Per-frame haze estimate: the dark channel prior's transmission.

Reuses :class:`cbnet_mmdet.utils.dark_channel.DarkChannelPrior`
(atmospheric light and refined transmission ``t``, the estimates the peer
baseline's dehazer also removes haze with); the statistic is the mean of
``t`` over the frame: near 1 on clear frames, lower in fog.
"""
import numpy as np
import torch

from cbnet_mmdet.utils.dark_channel import DarkChannelPrior


class HazeEstimator:
    """Mean DCP transmission of a BGR uint8 frame.

    Args:
        max_side (int): the frame is subsampled (by striding) until its
            longer side is at most this, pixels, to keep the edge cost
            low. Defaults to 256.
        **dcp_kwargs: arguments of ``DarkChannelPrior``.
    """

    def __init__(self, max_side: int = 256, **dcp_kwargs) -> None:
        if max_side < 1:
            raise ValueError(f'HazeEstimator: max_side must be >= 1, got '
                             f'{max_side}')
        self.max_side = max_side
        self.dcp = DarkChannelPrior(**dcp_kwargs)

    def __call__(self, img_bgr: np.ndarray) -> float:
        if img_bgr.ndim != 3 or img_bgr.shape[2] != 3 or img_bgr.size == 0:
            raise ValueError('HazeEstimator: expected an HxWx3 image, got '
                             f'shape {img_bgr.shape}')
        step = max(1, -(-max(img_bgr.shape[:2]) // self.max_side))
        rgb = np.ascontiguousarray(img_bgr[::step, ::step, ::-1])
        x = torch.from_numpy(rgb).permute(2, 0, 1)[None].float() / 255
        with torch.no_grad():
            light = self.dcp.atmospheric_light(x, self.dcp.dark_channel(x))
            t = self.dcp.transmission(x, light)
        return float(t.mean())
