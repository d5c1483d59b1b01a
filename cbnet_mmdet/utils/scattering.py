"""The atmospheric scattering model, the project's one fog model.

Foggy Cityscapes (Sakaridis et al., IJCV 2018) renders fog with Koschmieder's
model::

    I = J t + A (1 - t),    t = exp(-beta d)

``J`` the clear image, ``A`` the atmospheric light on the same scale as
``J``, ``t`` the transmission, ``beta`` the attenuation coefficient in 1/m
(meteorological visibility ``2.996 / beta``: 150 m at 0.02) and ``d`` the
distance in metres. Every fog of the project is this model: the renderer of
the generated scenes (``cbnet_tools.synthetic.add_fog``, ``d`` the scene's
depth), the transform ``CBNetAddFog`` (``d`` a prior from the image row) and,
solved for ``J``, the peer baseline's dark channel dehazer; the dark
channel prior's estimates of ``A`` and ``t`` are in
:mod:`cbnet_mmdet.utils.dark_channel`.

Not a registered component: the helper of ``CBNetAddFog``, which imports it.
"""
import math
import numbers

import numpy as np

#: Atmospheric light of the generated foggy scenes and ``CBNetAddFog``'s
#: default, RGB in [0, 1] (a bright grey, as estimated for most Foggy
#: Cityscapes images).
ATMOSPHERIC_LIGHT = (0.82, 0.83, 0.85)


def check_beta(beta, name: str = 'fog') -> float:
    """``beta`` as a float, refused unless a finite number >= 0 (1/m).

    Raises:
        TypeError: not a real number (a bool is refused too).
        ValueError: negative, NaN or infinite.
    """
    if not isinstance(beta, numbers.Real) or isinstance(beta, bool):
        raise TypeError(f'{name}: beta must be a number (1/m), got '
                        f'{beta!r}')
    if not math.isfinite(beta) or beta < 0:
        raise ValueError(f'{name}: beta must be a finite number >= 0 '
                         f'(1/m), got {beta}')
    return float(beta)


def transmission(distance: np.ndarray, beta: float) -> np.ndarray:
    """``t = exp(-beta d)``.

    Args:
        distance (np.ndarray): ``d``, metres, >= 0, any shape (``float[H]``
            per row, ``float[H, W]`` per pixel).
        beta (float): Attenuation coefficient, 1/m, finite, >= 0.

    Returns:
        np.ndarray: ``t`` in (0, 1], ``distance``'s shape, float64 (the
        dtype of ``distance`` where that is float32).

    Raises:
        TypeError, ValueError: a malformed ``beta``
            (:func:`check_beta`); ValueError: a negative or NaN distance.
    """
    beta = check_beta(beta, 'transmission')
    distance = np.asarray(distance)
    if not (distance >= 0).all():
        raise ValueError('transmission: distances must be >= 0 metres (no '
                         'NaN), got a minimum of '
                         f'{np.nanmin(distance) if distance.size else None}')
    return np.exp(-beta * distance)


def scatter(clear: np.ndarray, t: np.ndarray,
            light: np.ndarray) -> np.ndarray:
    """``I = J t + A (1 - t)``, with numpy's broadcasting and dtypes.

    The result is computed in the dtype numpy gives ``clear * t`` and
    ``light * (1 - t)`` (float32 for a ``uint8`` image with a float32
    ``t`` and ``light``), not rounded or clipped: that is the caller's.

    Args:
        clear (np.ndarray): ``J``, e.g. ``[H, W, 3]``.
        t (np.ndarray): Transmission in [0, 1], broadcastable to ``clear``
            (``[H, W, 1]`` per pixel, ``[H, 1, 1]`` per row).
        light (np.ndarray): ``A`` on the scale of ``clear``, broadcastable
            to it (``[3]`` per channel).

    Returns:
        np.ndarray: ``I``, of the broadcast shape.

    Raises:
        ValueError: ``clear``, ``t`` and ``light`` do not broadcast
            together, or ``clear`` and the result differ in shape.
    """
    clear, t, light = np.asarray(clear), np.asarray(t), np.asarray(light)
    try:
        shape = np.broadcast_shapes(clear.shape, t.shape, light.shape)
    except ValueError:
        raise ValueError(f'scatter: the image {clear.shape}, transmission '
                         f'{t.shape} and light {light.shape} do not '
                         'broadcast together') from None
    if shape != clear.shape:
        raise ValueError(f'scatter: the transmission {t.shape} and light '
                         f'{light.shape} would change the image\'s shape '
                         f'{clear.shape} to {shape}')
    foggy = clear * t
    haze = light * (1 - t)
    if foggy.dtype == np.result_type(foggy, haze):
        foggy += haze  # in place: the same sum, one array less
        return foggy
    return foggy + haze


def recover(hazy, t, light):
    """``J = (I - A) / t + A``: the model solved for the clear image.

    Any array type with arithmetic (numpy arrays, torch tensors), any
    broadcastable shapes; ``t`` must be > 0 (the dark channel prior's is
    bounded below by its ``t0``).

    Args:
        hazy: ``I``.
        t: Transmission in (0, 1].
        light: ``A`` on the scale of ``hazy``.

    Returns:
        ``J``, unclipped.
    """
    return (hazy - light) / t + light
