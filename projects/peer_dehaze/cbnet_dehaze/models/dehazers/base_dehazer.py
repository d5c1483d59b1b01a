"""Common interface of the dehazing modules."""
from abc import ABCMeta, abstractmethod

import torch
from mmengine.model import BaseModule
from torch import Tensor

#: Tolerance above 1.0 accepted on [0, 1] inputs (rounding of /255).
RANGE_TOL = 1e-3


def to_rgb3(img: Tensor, name: str = 'dehazer') -> Tensor:
    """Validate a batch of [0, 1] images and make it 3-channel.

    Args:
        img (Tensor[B, C, H, W]): float images in [0, 1]; C = 3 (RGB) or 1
            (grey, replicated to 3 channels).
        name (str): Who checks, for the error messages.

    Returns:
        Tensor[B, 3, H, W]: the images (the same tensor when C = 3).

    Raises:
        TypeError: not a floating-point tensor.
        ValueError: not 4-D, 0 height/width, 2 or 4+ channels (RGBA is
            refused: drop or composite the alpha channel first, e.g. load
            with ``color_type='color'``), values outside [0, 1] (a 0-255
            image?) or non-finite values.
    """
    if not isinstance(img, Tensor) or not img.is_floating_point():
        raise TypeError(f'{name}: expected a float Tensor[B, 3, H, W] in '
                        f'[0, 1], got {type(img).__name__} '
                        f'{getattr(img, "dtype", "")}')
    if img.dim() != 4:
        raise ValueError(f'{name}: expected Tensor[B, C, H, W], got shape '
                         f'{tuple(img.shape)}')
    channels, height, width = img.shape[1:]
    if height == 0 or width == 0:
        raise ValueError(f'{name}: empty image of size {height}x{width}')
    if channels == 1:
        img = img.expand(-1, 3, -1, -1)
    elif channels == 4:
        raise ValueError(
            f'{name}: got a 4-channel (RGBA?) image; drop or composite the '
            f'alpha channel first (mmcv loads 3 channels with '
            f"color_type='color')")
    elif channels != 3:
        raise ValueError(f'{name}: expected 3 (RGB) or 1 (grey) channels, '
                         f'got {channels}')
    if img.numel():
        if not torch.isfinite(img).all():
            raise ValueError(f'{name}: input has NaN or Inf values')
        low, high = img.min().item(), img.max().item()
        if low < -RANGE_TOL or high > 1 + RANGE_TOL:
            raise ValueError(
                f'{name}: expected values in [0, 1], got [{low:.3g}, '
                f'{high:.3g}] (divide 0-255 images by 255)')
    return img


class BaseDehazer(BaseModule, metaclass=ABCMeta):
    """A module that maps hazy images to haze-free ones.

    Every dehazer takes and returns ``Tensor[B, 3, H, W]`` RGB images with
    values in [0, 1], of any height and width; 1-channel (grey) inputs are
    replicated to 3 channels, other channel counts are refused
    (:func:`to_rgb3`). Subclasses implement :meth:`dehaze`; the output is
    clamped to [0, 1].
    """

    @abstractmethod
    def dehaze(self, img: Tensor) -> Tensor:
        """Dehaze validated images.

        Args:
            img (Tensor[B, 3, H, W]): RGB in [0, 1], B >= 1.

        Returns:
            Tensor[B, 3, H, W]: the dehazed images (any range; clamped by
            :meth:`forward`).
        """

    def forward(self, img: Tensor) -> Tensor:
        """Dehaze a batch.

        Args:
            img (Tensor[B, C, H, W]): RGB (C = 3) or grey (C = 1) images,
                float in [0, 1].

        Returns:
            Tensor[B, 3, H, W]: dehazed RGB images in [0, 1].
        """
        img = to_rgb3(img, type(self).__name__)
        if img.shape[0] == 0:
            return img.clone()
        return self.dehaze(img).clamp(0.0, 1.0)
