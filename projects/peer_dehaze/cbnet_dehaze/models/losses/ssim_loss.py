"""Structural similarity (SSIM) and the ``1 - SSIM`` loss."""
from typing import Optional

import torch
import torch.nn.functional as F
from mmdet.registry import MODELS
from torch import Tensor, nn

#: SSIM stabilisers K1, K2 (Wang et al. 2004).
K1, K2 = 0.01, 0.03


def gaussian_window(size: int, sigma: float, device=None,
                    dtype=torch.float32) -> Tensor:
    """Normalised 1-D Gaussian, Tensor[size]."""
    x = torch.arange(size, device=device, dtype=dtype) - (size - 1) / 2
    w = torch.exp(-x**2 / (2 * sigma**2))
    return w / w.sum()


def ssim(x: Tensor,
         y: Tensor,
         window_size: int = 11,
         sigma: float = 1.5,
         data_range: float = 1.0) -> Tensor:
    """Mean SSIM per image (Wang, Bovik, Sheikh, Simoncelli 2004).

    Gaussian-weighted local statistics (``window_size`` taps, ``sigma``
    pixels, separable), computed per channel on the valid region only (no
    padding), averaged over channels and pixels; population (biased)
    variances. Matches scikit-image's ``structural_similarity`` with
    ``gaussian_weights=True, use_sample_covariance=False``. Images smaller
    than the window use the largest odd window that fits.

    Args:
        x, y (Tensor[B, C, H, W]): images to compare.
        window_size (int): odd window side, pixels. Defaults to 11.
        sigma (float): Gaussian sigma, pixels. Defaults to 1.5.
        data_range (float): value range of the images (1 for [0, 1]).

    Returns:
        Tensor[B]: SSIM in [-1, 1] per image (1: identical).
    """
    if x.shape != y.shape or x.dim() != 4:
        raise ValueError(f'ssim: expected two Tensor[B, C, H, W] of one '
                         f'shape, got {tuple(x.shape)} and {tuple(y.shape)}')
    size = min(window_size, x.shape[-2], x.shape[-1])
    size -= 1 - size % 2  # odd
    if size < 1:
        raise ValueError(f'ssim: empty image {tuple(x.shape)}')
    c = x.shape[1]
    w = gaussian_window(size, sigma, x.device, x.dtype)
    wh = w.view(1, 1, size, 1).repeat(c, 1, 1, 1)
    ww = w.view(1, 1, 1, size).repeat(c, 1, 1, 1)

    def blur(t: Tensor) -> Tensor:
        return F.conv2d(F.conv2d(t, wh, groups=c), ww, groups=c)

    mu_x, mu_y = blur(x), blur(y)
    var_x = blur(x * x) - mu_x**2
    var_y = blur(y * y) - mu_y**2
    cov = blur(x * y) - mu_x * mu_y
    c1, c2 = (K1 * data_range)**2, (K2 * data_range)**2
    smap = ((2 * mu_x * mu_y + c1) * (2 * cov + c2)) / (
        (mu_x**2 + mu_y**2 + c1) * (var_x + var_y + c2))
    return smap.flatten(1).mean(1)


@MODELS.register_module()
class CBNetSSIMLoss(nn.Module):
    """``loss_weight * (1 - SSIM)``, averaged over the batch.

    Args:
        window_size (int): Gaussian window side. Defaults to 11.
        sigma (float): Gaussian sigma, pixels. Defaults to 1.5.
        data_range (float): Image value range. Defaults to 1.
        loss_weight (float): Weight. Defaults to 1.
    """

    def __init__(self,
                 window_size: int = 11,
                 sigma: float = 1.5,
                 data_range: float = 1.0,
                 loss_weight: float = 1.0) -> None:
        super().__init__()
        self.window_size = window_size
        self.sigma = sigma
        self.data_range = data_range
        self.loss_weight = loss_weight

    def forward(self, pred: Tensor, target: Tensor,
                weight: Optional[Tensor] = None) -> Tensor:
        """Tensor[B, C, H, W] x2 -> scalar loss (0 for an empty batch)."""
        if pred.shape[0] == 0:
            return pred.sum() * 0
        per_image = 1 - ssim(pred, target, self.window_size, self.sigma,
                             self.data_range)
        if weight is not None:
            per_image = per_image * weight
        return self.loss_weight * per_image.mean()
