"""The dark channel prior's estimates (He, Sun, Tang, CVPR 2009 / TPAMI
2011): dark channel, atmospheric light and the guided-filter-refined
transmission of the scattering model ``I = J t + A (1 - t)``
(:mod:`cbnet_mmdet.utils.scattering`).

Not a registered component: the one home of these estimates, for every
caller. ``CBNetAddFog`` (``atmospheric_light='dark_channel'``) takes ``A``
from :func:`dark_channel` and :func:`atmospheric_light`; the peer baseline's
training-free dehazer ``CBNetDarkChannelPrior`` (``cbnet_dehaze``) is a
:class:`DarkChannelPrior` that recovers ``J`` from ``A`` and ``t``; the
edge-serving project's haze score (``cbnet_serving.haze.HazeEstimator``) is
the mean of its ``t``. They live in the plugin because a plugin transform
uses them, and the plugin imports neither project.
"""
import numbers

import torch
import torch.nn.functional as F
from torch import Tensor

#: Rec. 601 luma weights of R, G, B (the guided filter's grey guide).
LUMA = (0.299, 0.587, 0.114)
#: He et al.'s dark channel window side, pixels.
PATCH_SIZE = 15
#: He et al.'s fraction of the largest dark-channel pixels searched for the
#: atmospheric light (0.1%).
TOP_FRACTION = 0.001


def _min_along(x: Tensor, size: int, dim: int) -> Tensor:
    """Minimum over windows of ``size`` (odd) along ``dim`` (2 or 3),
    clipped to the image: padded with +inf, then minima of windows of 1,
    2, 4, ... doubled by one shifted ``torch.minimum`` each, and the last
    window of ``size`` from two overlapping power-of-two windows."""
    n, r = x.shape[dim], size // 2
    x = F.pad(x, (r, r) if dim == 3 else (0, 0, r, r), value=float('inf'))
    width = 1  # x[i] is the minimum of the padded input's [i, i + width)
    while 2 * width <= size:
        m = x.shape[dim] - width
        x = torch.minimum(x.narrow(dim, 0, m), x.narrow(dim, width, m))
        width *= 2
    if width < size:
        x = torch.minimum(x.narrow(dim, 0, n), x.narrow(dim, size - width, n))
    return x


def min_filter(x: Tensor, size: int) -> Tensor:
    """Minimum over ``size x size`` windows clipped to the image.

    Separable (rows then columns), each in ``O(log size)`` elementwise
    minima of shifted views (a minimum is exact: the same values as any
    other way of taking it, e.g. max-pooling ``-x``, which took 35-40x as
    long on one CPU thread at 15 px, 480x640 and 512x1024).

    Args:
        x (Tensor[B, C, H, W]): input, floating point.
        size (int): odd window side, pixels.

    Returns:
        Tensor[B, C, H, W].
    """
    return _min_along(_min_along(x, size, 3), size, 2)


def box_mean(x: Tensor, radius: int) -> Tensor:
    """Mean over ``(2r+1)^2`` windows clipped to the image, in O(HW).

    Separable running sums (cumulative sums along W, then H), each
    normalised by the number of pixels inside the image, as He's guided
    filter divides by the box filter of ones.

    Args:
        x (Tensor[B, C, H, W]): input.
        radius (int): window radius r >= 0, pixels.

    Returns:
        Tensor[B, C, H, W].
    """
    for dim in (3, 2):
        n = x.shape[dim]
        csum = F.pad(x.cumsum(dim), (1, 0) if dim == 3 else (0, 0, 1, 0))
        idx = torch.arange(n, device=x.device)
        hi = (idx + radius + 1).clamp(max=n)
        lo = (idx - radius).clamp(min=0)
        count = (hi - lo).to(x.dtype)
        shape = [1, 1, 1, 1]
        shape[dim] = n
        x = (csum.index_select(dim, hi) -
             csum.index_select(dim, lo)) / count.view(shape)
    return x


def guided_filter(guide: Tensor, src: Tensor, radius: int,
                  eps: float) -> Tensor:
    """He's guided filter with a grey guide (He, Sun, Tang, ECCV 2010).

    Args:
        guide (Tensor[B, 1, H, W]): guidance image.
        src (Tensor[B, 1, H, W]): image to filter.
        radius (int): window radius, pixels.
        eps (float): regularisation of the local linear model.

    Returns:
        Tensor[B, 1, H, W]: ``mean(a) * guide + mean(b)``.
    """
    mean_i = box_mean(guide, radius)
    mean_p = box_mean(src, radius)
    cov_ip = box_mean(guide * src, radius) - mean_i * mean_p
    var_i = box_mean(guide * guide, radius) - mean_i * mean_i
    a = cov_ip / (var_i + eps)
    b = mean_p - a * mean_i
    return box_mean(a, radius) * guide + box_mean(b, radius)


def _check_patch_size(patch_size: int, name: str) -> None:
    if isinstance(patch_size, bool) or \
            not isinstance(patch_size, numbers.Integral) or \
            patch_size < 1 or patch_size % 2 == 0:
        raise ValueError(f'{name}: patch_size must be odd and positive, '
                         f'got {patch_size}')


def _check_images(img: Tensor, name: str) -> None:
    """Refuse what is not a non-empty ``Tensor[B, 3, H, W]``."""
    if not isinstance(img, Tensor):
        raise TypeError(f'{name}: expected a Tensor[B, 3, H, W], got '
                        f'{type(img).__name__}')
    if img.dim() != 4 or img.shape[1] != 3:
        raise ValueError(f'{name}: expected Tensor[B, 3, H, W] (3 colour '
                         f'channels), got shape {tuple(img.shape)}')
    if img.numel() == 0:
        raise ValueError(f'{name}: empty images, shape {tuple(img.shape)}')


def dark_channel(img: Tensor, patch_size: int = PATCH_SIZE) -> Tensor:
    """``D(x) = min_{y in patch(x)} min_c I_c(y)``.

    Args:
        img (Tensor[B, 3, H, W]): images, any scale (the minimum is exact,
            so 0-255 and [0, 1] images give the same pixels).
        patch_size (int): odd window side, pixels; windows are clipped to
            the image.

    Returns:
        Tensor[B, 1, H, W].

    Raises:
        TypeError, ValueError: not a non-empty ``Tensor[B, 3, H, W]``, or
            an even or non-positive ``patch_size``.
    """
    _check_images(img, 'dark_channel')
    _check_patch_size(patch_size, 'dark_channel')
    return min_filter(img.amin(dim=1, keepdim=True), patch_size)


def atmospheric_light(img: Tensor, dark: Tensor,
                      top_fraction: float = TOP_FRACTION) -> Tensor:
    """He et al.'s estimate of ``A``: among the ``top_fraction`` of pixels
    with the largest dark channel (at least one), the input pixel of
    highest intensity (R + G + B), per image.

    Args:
        img (Tensor[B, 3, H, W]): hazy images, any scale.
        dark (Tensor[B, 1, H, W]): their dark channels
            (:func:`dark_channel`).
        top_fraction (float): fraction of the pixels searched, in (0, 1].

    Returns:
        Tensor[B, 3]: that pixel of each image, ``img``'s scale and dtype,
        unbounded.

    Raises:
        TypeError, ValueError: ``img`` not a non-empty
            ``Tensor[B, 3, H, W]``, ``dark`` not its ``[B, 1, H, W]``, or
            ``top_fraction`` outside (0, 1].
    """
    _check_images(img, 'atmospheric_light')
    b, _, h, w = img.shape
    if not isinstance(dark, Tensor) or tuple(dark.shape) != (b, 1, h, w):
        raise ValueError(f'atmospheric_light: the dark channel must be '
                         f'Tensor[{b}, 1, {h}, {w}], got '
                         f'{tuple(getattr(dark, "shape", ()))}')
    if not 0 < top_fraction <= 1:
        raise ValueError(f'atmospheric_light: top_fraction must be in '
                         f'(0, 1], got {top_fraction}')
    k = max(1, int(h * w * top_fraction))
    top = dark.reshape(b, -1).topk(k, dim=1).indices  # [B, k]
    pixels = img.reshape(b, 3, -1).gather(
        2, top.unsqueeze(1).expand(-1, 3, -1))  # [B, 3, k]
    best = pixels.sum(dim=1).argmax(dim=1)  # [B]
    return pixels[torch.arange(b, device=img.device), :, best]


class DarkChannelPrior:
    """Dark channel, atmospheric light ``A`` and transmission ``t``.

    1. dark channel ``D(x) = min_{y in patch(x)} min_c I_c(y)``;
    2. atmospheric light ``A``: among the brightest ``top_fraction`` of
       ``D``, the input pixel of highest intensity (R+G+B), per image;
    3. transmission ``t = 1 - omega * dark(I / A)``;
    4. refinement of ``t`` by the guided filter (grey input as guide).

    Every step is batched tensor code (no per-image loop, no OpenCV), so it
    runs on CPU and CUDA for any B, H, W. Inputs are ``Tensor[B, 3, H, W]``
    RGB in [0, 1].

    Args:
        patch_size (int): Dark channel window side, odd, pixels. Defaults
            to 15 (He et al.).
        omega (float): Haze kept for depth perception, in (0, 1].
            Defaults to 0.95.
        t0 (float): Lower bound of the transmission. Defaults to 0.1.
        top_fraction (float): Fraction of dark-channel pixels searched for
            ``A``. Defaults to 0.001 (0.1%).
        guided_radius (int): Guided filter radius, pixels. Defaults to 40
            (He et al. use 60 at 600x400; smaller keeps detail on
            Cityscapes' small far objects).
        guided_eps (float): Guided filter regularisation. Defaults to 1e-3.
        min_atmosphere (float): Lower bound of ``A`` per channel (keeps
            all-black frames finite). Defaults to 0.05.
    """

    def __init__(self,
                 patch_size: int = PATCH_SIZE,
                 omega: float = 0.95,
                 t0: float = 0.1,
                 top_fraction: float = TOP_FRACTION,
                 guided_radius: int = 40,
                 guided_eps: float = 1e-3,
                 min_atmosphere: float = 0.05) -> None:
        name = type(self).__name__
        _check_patch_size(patch_size, name)
        if not 0 < omega <= 1 or not 0 < t0 <= 1:
            raise ValueError(f'{name}: omega and t0 must be in (0, 1], '
                             f'got {omega}, {t0}')
        if not 0 < top_fraction <= 1 or guided_radius < 0:
            raise ValueError(f'{name}: top_fraction must be in (0, 1] and '
                             'guided_radius >= 0')
        self.patch_size = patch_size
        self.omega = omega
        self.t0 = t0
        self.top_fraction = top_fraction
        self.guided_radius = guided_radius
        self.guided_eps = guided_eps
        self.min_atmosphere = min_atmosphere

    def dark_channel(self, img: Tensor) -> Tensor:
        """Tensor[B, 3, H, W] -> dark channel Tensor[B, 1, H, W]
        (:func:`dark_channel`)."""
        return dark_channel(img, self.patch_size)

    def atmospheric_light(self, img: Tensor, dark: Tensor) -> Tensor:
        """Estimate ``A`` per image.

        Args:
            img (Tensor[B, 3, H, W]): hazy images.
            dark (Tensor[B, 1, H, W]): their dark channels.

        Returns:
            Tensor[B, 3, 1, 1]: atmospheric light
            (:func:`atmospheric_light`), >= ``min_atmosphere``.
        """
        light = atmospheric_light(img, dark, self.top_fraction)
        return light.clamp(min=self.min_atmosphere).view(-1, 3, 1, 1)

    def transmission(self, img: Tensor, light: Tensor) -> Tensor:
        """Refined transmission ``t`` in [t0, 1], Tensor[B, 1, H, W]."""
        raw = 1 - self.omega * self.dark_channel(img / light)
        guide = sum(w * img[:, i:i + 1] for i, w in enumerate(LUMA))
        refined = guided_filter(guide, raw, self.guided_radius,
                                self.guided_eps)
        return refined.clamp(self.t0, 1.0)
