"""Synthetic fog on any photograph: the atmospheric scattering model with a
ground-plane depth prior from the image row (no depth map needed)."""
import math
import numbers
from typing import Optional, Sequence, Tuple, Union

import numpy as np
import torch
from mmcv.transforms import BaseTransform
from mmcv.transforms.utils import cache_randomness
from mmdet.registry import TRANSFORMS

from cbnet_mmdet.utils import dark_channel, scattering
from cbnet_mmdet.utils.scattering import ATMOSPHERIC_LIGHT

#: Defaults of the row prior's camera: those of the generated scenes (and
#: close to Cityscapes' camera), so a ``beta`` means the same fog here and in
#: the project's depth-rendered Foggy Cityscapes-like images.
#: Camera height above the road, metres.
CAMERA_HEIGHT = 1.3
#: Focal length as a fraction of the image width (Cityscapes: 2262 px at
#: 2048 px, a 48 deg horizontal field of view).
FOCAL_PER_WIDTH = 1.1
#: Horizon row as a fraction of the image height.
HORIZON = 0.45
#: Height above the camera of the "ceiling" plane that gives rows above the
#: horizon their distance, metres. Fit on 6 generated scenes (256 x 512,
#: seed 1; 1, 2, 3, 5, 8, 12, 20, 40 m tried): the mean absolute difference
#: to their depth-rendered fog at beta 0.005 / 0.01 / 0.02 is 11.8 / 15.3 /
#: 17.6 grey levels with 2 m (the lowest mean over the three), 11.2 / 15.1 /
#: 18.6 with 1 m, 15.0 / 18.4 / 19.4 with 5 m and 34.8 / 33.2 / 27.5 without
#: a ceiling (everything above the horizon at MAX_DISTANCE).
CEILING_HEIGHT = 2.0
#: Distance of the horizon row, the far clamp of both planes, metres (the
#: generated scenes' sky).
MAX_DISTANCE = 600.0

LightType = Union[float, Sequence[float], str]


def _is_number(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _check_beta(beta) -> Union[float, Tuple[float, float]]:
    """A fixed ``beta`` or a ``(low, high)`` range, both in 1/m, >= 0."""
    name = 'CBNetAddFog'
    if _is_number(beta):
        return scattering.check_beta(beta, name)
    if isinstance(beta, (tuple, list)) and len(beta) == 2 and all(
            _is_number(b) for b in beta):
        low, high = beta
        if not (math.isfinite(low) and math.isfinite(high)) or low < 0:
            raise ValueError(f'{name}: a beta range (low, high) needs '
                             f'finite bounds >= 0 (1/m), got {tuple(beta)}')
        if low > high:
            raise ValueError(f'{name}: beta range (low, high) is reversed: '
                             f'{tuple(beta)}; write ({high}, {low})')
        return float(low), float(high)
    raise TypeError(f'{name}: beta must be a number or a (low, high) pair '
                    f'of numbers, in 1/m; got {beta!r}')


def _check_light(light: LightType) -> Union[str, Tuple[float, ...]]:
    """``'dark_channel'``, a grey level or an RGB triple in [0, 1]."""
    name = 'CBNetAddFog'
    if isinstance(light, str):
        if light != 'dark_channel':
            raise ValueError(f"{name}: atmospheric_light must be "
                             f"'dark_channel', a number or an (R, G, B) "
                             f"triple in [0, 1]; got {light!r}")
        return light
    values = (light, ) * 3 if _is_number(light) else light
    if not (isinstance(values, (tuple, list)) and len(values) == 3
            and all(_is_number(v) and 0 <= v <= 1 for v in values)):
        raise ValueError(f"{name}: atmospheric_light must be "
                         f"'dark_channel', a number or an (R, G, B) triple "
                         f"in [0, 1] (fractions of 255); got {light!r}")
    return tuple(float(v) for v in values)


@TRANSFORMS.register_module()
class CBNetAddFog(BaseTransform):
    """Add homogeneous fog to a photograph that has no depth map.

    The atmospheric scattering model that renders Foggy Cityscapes
    (Sakaridis et al., IJCV 2018) and the project's generated foggy scenes
    (:mod:`cbnet_mmdet.utils.scattering`, the renderer's too)::

        I = J t + 255 A (1 - t),    t = exp(-beta d)

    with ``J`` the clear image (0-255), ``A`` the atmospheric light in
    [0, 1] per channel, ``beta`` the attenuation coefficient in 1/m
    (meteorological visibility ``2.996 / beta``: 150 m at 0.02) and ``d``
    the distance in metres, here a **prior from the image row** instead of
    a measured depth: a level pinhole camera at height ``h``
    (``camera_height``) between a flat road and a "ceiling" plane ``c``
    (``ceiling_height``) above it, focal length ``f = focal_length * W``
    pixels, horizon at row ``v_h = horizon * H``; the plane seen at the
    centre of row ``i`` (``v = i + 0.5``) is at depth along the optical axis

        d(v) = min(h f / (v - v_h), max_distance)   for v > v_h (road),
        d(v) = min(c f / (v_h - v), max_distance)   for v < v_h (ceiling),
        d(v) = max_distance                          for v = v_h

    (``ceiling_height=None``: ``max_distance`` for every ``v <= v_h``).
    Distance grows towards the horizon row from both sides. Every pixel of
    a row gets that row's distance: the road is where the prior is right;
    an upright object (car, pedestrian, facade) gets its rows' distances
    instead of its own, and the sky less fog than its real distance would
    give (it is close to ``A`` already). The ceiling stands for what rises
    above the horizon near a street camera (vehicles, facades, trees):
    without it, everything above the horizon would be at ``max_distance``
    and vanish even at beta 0.005 (``t = exp(-3)``). The defaults are the
    camera of the generated scenes (1.3 m, 1.1 W, 0.45 H, 600 m), close to
    Cityscapes', so ``beta`` means the same density as in Foggy Cityscapes
    (0.005, 0.01, 0.02); ``c = 2`` m is the value that fits their
    depth-rendered fog best (:data:`CEILING_HEIGHT`).

    Photometric only: boxes, masks, labels and image size are untouched.
    ``beta = 0`` returns the image unchanged (``t = 1``). The output keeps
    the input's dtype and shape: ``uint8`` images (``LoadImageFromFile``)
    are rounded to the nearest integer; ``float32``/``float64`` images
    (``LoadImageFromFile(to_float32=True)``), taken on the 0-255 scale, are
    not rounded. Other dtypes raise ``TypeError``; images that are not
    ``H x W x 3`` (grey ``H x W`` or ``H x W x 1``, RGBA, the stacked
    6-channel pairs of ``CBNetLoadPairedImageFromFile``) raise
    ``ValueError``: load photographs with ``color_type='color'`` (the
    default; grey files become 3 equal channels), and use
    :class:`CBNetAddFoggyTwin` for clear/foggy pairs.

    Randomness (whether to fog, ``beta`` of a range) is drawn from numpy's
    global generator like MMCV's random transforms, which MMEngine seeds
    (``randomness=dict(seed=...)``, per dataloader worker): the same seed
    gives the same fog.

    Required keys: ``img``. Modified keys: ``img``. Added keys:
    ``fog_beta`` (the ``beta`` applied, 1/m; 0.0 when ``prob`` skipped the
    image) and ``fog_light`` (``A`` used, in the image's channel order,
    [0, 1]; None when skipped); add them to ``PackDetInputs``'
    ``meta_keys`` to log them.

    Args:
        beta (float | tuple[float, float]): Attenuation coefficient, 1/m,
            >= 0; a ``(low, high)`` pair draws it uniformly per image.
            Defaults to 0.01.
        prob (float): Probability of fogging an image, in [0, 1].
            Defaults to 1.0.
        atmospheric_light (float | tuple[float, float, float] | str): ``A``,
            one grey level or ``(R, G, B)``, in [0, 1] (RGB whatever
            ``channel_order``); or ``'dark_channel'``: estimated on each
            image as He et al. do, the brightest pixel (largest B+G+R) among
            the 0.1% brightest pixels of its dark channel (minimum over
            channels and a 15 x 15 window; the estimate of
            :mod:`cbnet_mmdet.utils.dark_channel`, which the peer
            baseline's dehazer uses too, in torch on the CPU). Defaults to
            (0.82, 0.83, 0.85), the light of the generated foggy scenes.
        channel_order (str): ``'bgr'`` (``LoadImageFromFile``'s default) or
            ``'rgb'``: where R, G, B of ``atmospheric_light`` go.
        camera_height (float): ``h``, metres, > 0. Defaults to 1.3.
        focal_length (float): ``f`` as a fraction of the image width, > 0.
            Defaults to 1.1.
        horizon (float): Horizon row as a fraction of the image height
            (may lie outside [0, 1] for a camera pitched up or down).
            Defaults to 0.45.
        ceiling_height (float, optional): ``c``, metres above the camera,
            > 0; None puts every row above the horizon at
            ``max_distance``. Defaults to 2.0.
        max_distance (float): Distance of the horizon row and far clamp,
            metres, > 0. Defaults to 600.
    """

    def __init__(self,
                 beta: Union[float, Sequence[float]] = 0.01,
                 prob: float = 1.0,
                 atmospheric_light: LightType = ATMOSPHERIC_LIGHT,
                 channel_order: str = 'bgr',
                 camera_height: float = CAMERA_HEIGHT,
                 focal_length: float = FOCAL_PER_WIDTH,
                 horizon: float = HORIZON,
                 ceiling_height: Optional[float] = CEILING_HEIGHT,
                 max_distance: float = MAX_DISTANCE) -> None:
        name = type(self).__name__
        self.beta = _check_beta(beta)
        if not _is_number(prob) or not 0 <= prob <= 1:
            raise ValueError(f'{name}: prob must be in [0, 1], got {prob!r}')
        self.prob = float(prob)
        self.atmospheric_light = _check_light(atmospheric_light)
        if channel_order not in ('bgr', 'rgb'):
            raise ValueError(f"{name}: channel_order must be 'bgr' or "
                             f"'rgb', got {channel_order!r}")
        self.channel_order = channel_order
        positive = dict(
            camera_height=camera_height,
            focal_length=focal_length,
            max_distance=max_distance)
        if ceiling_height is not None:
            positive['ceiling_height'] = ceiling_height
        for key, value in positive.items():
            if not _is_number(value) or not 0 < value < math.inf:
                raise ValueError(f'{name}: {key} must be a finite number '
                                 f'> 0, got {value!r}')
        if not _is_number(horizon) or not math.isfinite(horizon):
            raise ValueError(f'{name}: horizon must be a finite fraction '
                             f'of the image height, got {horizon!r}')
        self.camera_height = float(camera_height)
        self.focal_length = float(focal_length)
        self.horizon = float(horizon)
        self.ceiling_height = (None if ceiling_height is None else
                               float(ceiling_height))
        self.max_distance = float(max_distance)

    def distance(self, height: int, width: int) -> np.ndarray:
        """Row prior ``d(v)`` of an ``height x width`` image,
        ``float64[H]``, metres."""
        rows = np.arange(height) + 0.5 - self.horizon * height
        focal = self.focal_length * width
        far = np.full(height, self.max_distance)
        with np.errstate(divide='ignore'):
            road = self.camera_height * focal / rows
            ceiling = far
            if self.ceiling_height is not None:
                ceiling = self.ceiling_height * focal / -rows
        depth = np.where(rows > 0, road, np.where(rows < 0, ceiling, far))
        return np.minimum(depth, self.max_distance)

    def transmission(self, height: int, width: int, beta: float) -> np.ndarray:
        """``t = exp(-beta d(v))`` per row, ``float64[H]`` in (0, 1]
        (:func:`cbnet_mmdet.utils.scattering.transmission`)."""
        return scattering.transmission(self.distance(height, width), beta)

    def light(self, img: np.ndarray) -> np.ndarray:
        """``A`` for ``img`` in its channel order, ``float64[3]``, [0, 1]."""
        if self.atmospheric_light == 'dark_channel':
            return self._dark_channel_light(img)
        light = np.asarray(self.atmospheric_light, np.float64)
        return light[::-1].copy() if self.channel_order == 'bgr' else light

    @staticmethod
    def _dark_channel_light(img: np.ndarray) -> np.ndarray:
        """He et al.'s ``A`` of ``img``, in [0, 1]
        (:mod:`cbnet_mmdet.utils.dark_channel` with its window and
        fraction). Where pixels tie at the 0.1% cut of the dark channel,
        which of them are searched is ``torch.topk``'s choice, as in the
        peer baseline's dehazer."""
        # a [1, 3, H, W] copy in the image's channel order (minimum and
        # R + G + B do not depend on it); float32 holds uint8 values and
        # their sums exactly, float images are searched in float64
        dtype = np.float32 if img.dtype == np.uint8 else np.float64
        x = torch.from_numpy(
            np.array(img.transpose(2, 0, 1), dtype=dtype, order='C'))[None]
        with torch.no_grad():
            best = dark_channel.atmospheric_light(
                x, dark_channel.dark_channel(x))[0]
        return np.clip(best.numpy().astype(np.float64) / 255.0, 0.0, 1.0)

    @cache_randomness
    def _sample_beta(self) -> float:
        """The ``beta`` of one image; 0.0 when ``prob`` skips it."""
        if np.random.rand() >= self.prob:
            return 0.0
        if isinstance(self.beta, tuple):
            return float(np.random.uniform(*self.beta))
        return self.beta

    def _check_image(self, results: dict) -> np.ndarray:
        name = type(self).__name__
        img = results.get('img')
        where = results.get('img_path') or 'the input array'
        if not isinstance(img, np.ndarray):
            raise TypeError(f'{name}: results["img"] of {where} must be a '
                            f'numpy image, got {type(img).__name__}')
        if img.ndim != 3 or img.shape[2] != 3:
            raise ValueError(
                f'{name}: the image of {where} has shape {img.shape}; fog '
                f'is added to H x W x 3 colour images (load grey files with '
                f"LoadImageFromFile's default color_type='color'; for "
                f'stacked clear/foggy pairs use CBNetAddFoggyTwin on the '
                f'clear image)')
        if img.dtype not in (np.uint8, np.float32, np.float64):
            raise TypeError(f'{name}: the image of {where} is {img.dtype}; '
                            f'uint8 or float32/float64 on the 0-255 scale '
                            f'are supported')
        return img

    def fog(self, img: np.ndarray,
            beta: float) -> Tuple[np.ndarray, np.ndarray]:
        """Fog one ``H x W x 3`` image at ``beta`` (1/m).

        Returns:
            tuple: the foggy image (``img``'s dtype and shape) and ``A``
            (``float64[3]``, the image's channel order).
        """
        light = self.light(img)
        h, w = img.shape[:2]
        # float32 for uint8 images (exact enough for rounding to 8 bits);
        # float images keep their precision
        ftype = np.float64 if img.dtype == np.float64 else np.float32
        t = self.transmission(h, w, beta).astype(ftype)[:, None]  # [H, 1]
        # rows of W * 3 values: contiguous operands (broadcasting over a
        # last axis of 3 is several times slower); A on the 0-255 scale
        haze_light = np.tile((255.0 * light).astype(ftype), w)  # [W * 3]
        out = scattering.scatter(img.reshape(h, w * 3), t, haze_light)
        if img.dtype == np.uint8:
            # a convex combination of two values in [0, 255]: no clipping
            np.rint(out, out=out)
        return out.astype(img.dtype, copy=False).reshape(img.shape), light

    def transform(self, results: dict) -> dict:
        """Fog ``results['img']`` in place of the clear image.

        Args:
            results (dict): With ``img`` (``H x W x 3``).

        Returns:
            dict: ``results`` with the foggy ``img``, ``fog_beta``,
            ``fog_light``.
        """
        img = self._check_image(results)
        beta = self._sample_beta()
        light = None
        if beta > 0:
            results['img'], light = self.fog(img, beta)
            light = tuple(float(v) for v in light)
        results['fog_beta'] = beta
        results['fog_light'] = light
        return results

    def __repr__(self) -> str:
        return (f'{type(self).__name__}(beta={self.beta}, prob={self.prob}, '
                f'atmospheric_light={self.atmospheric_light!r}, '
                f'channel_order={self.channel_order!r}, '
                f'camera_height={self.camera_height}, '
                f'focal_length={self.focal_length}, '
                f'horizon={self.horizon}, '
                f'ceiling_height={self.ceiling_height}, '
                f'max_distance={self.max_distance})')
