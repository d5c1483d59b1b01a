"""The atmospheric scattering model (cbnet_mmdet/utils/scattering.py)
against the formula computed here pixel by pixel in float64
(``t = exp(-beta d)``, ``I = J t + A (1 - t)``, ``J = (I - A) / t + A``),
and malformed input refused."""
import math

import numpy as np
import pytest
import torch

from cbnet_mmdet.utils.scattering import (ATMOSPHERIC_LIGHT, check_beta,
                                          recover, scatter, transmission)


def reference_fog(clear, depth, beta, light):
    """``[H, W, 3]`` clear image, ``[H, W]`` depth: the foggy image."""
    h, w, _ = clear.shape
    out = np.empty((h, w, 3))
    for i in range(h):
        for j in range(w):
            t = math.exp(-beta * float(depth[i, j]))
            for c in range(3):
                out[i, j, c] = float(clear[i, j, c]) * t + light[c] * (1 - t)
    return out


def test_the_generated_scenes_light():
    assert ATMOSPHERIC_LIGHT == (0.82, 0.83, 0.85)


@pytest.mark.parametrize('beta', [0.0, 0.005, 0.02, 0.3])
def test_transmission_against_exp(beta):
    depth = np.random.RandomState(0).uniform(0, 700, (5, 7))
    t = transmission(depth, beta)
    assert t.shape == (5, 7) and t.dtype == np.float64
    np.testing.assert_allclose(
        t, [[math.exp(-beta * d) for d in row] for row in depth],
        rtol=1e-14)
    assert (t > 0).all() and (t <= 1).all()
    if beta == 0:
        assert (t == 1).all()
    # per row, and at no distance at all
    assert transmission(np.array([0.0, 10.0]), beta)[0] == 1.0
    assert transmission(np.zeros((0, 4)), beta).shape == (0, 4)


@pytest.mark.parametrize('scale, light', [(1.0, ATMOSPHERIC_LIGHT),
                                          (255.0, (255.0, 100.0, 0.0))])
def test_scatter_against_pixel_loop(scale, light):
    rng = np.random.RandomState(1)
    clear = rng.rand(6, 8, 3) * scale
    depth = rng.uniform(0, 200, (6, 8))
    t = transmission(depth, 0.02)[..., None]
    got = scatter(clear, t, np.asarray(light))
    assert got.shape == clear.shape and got.dtype == np.float64
    np.testing.assert_allclose(got, reference_fog(clear, depth, 0.02, light),
                               rtol=1e-13, atol=1e-12)
    # no fog: the image; all fog: the light
    np.testing.assert_array_equal(
        scatter(clear, np.ones((6, 8, 1)), np.asarray(light)), clear)
    np.testing.assert_array_equal(
        scatter(clear, np.zeros((6, 8, 1)), np.asarray(light)),
        np.broadcast_to(light, clear.shape))


def test_scatter_dtypes_and_layouts():
    """A uint8 image with float32 t and light stays float32 (what a
    caller rounds); rows of W * 3 values with a per-row t and a tiled
    light give the same pixels as [H, W, 3] with [H, 1, 1]."""
    rng = np.random.RandomState(2)
    img = rng.randint(0, 256, (5, 4, 3)).astype(np.uint8)
    t = rng.rand(5).astype(np.float32)
    light = np.array([200.0, 210.0, 220.0], np.float32)
    cube = scatter(img, t[:, None, None], light)
    rows = scatter(img.reshape(5, 12), t[:, None], np.tile(light, 4))
    assert cube.dtype == rows.dtype == np.float32
    np.testing.assert_array_equal(rows.reshape(5, 4, 3), cube)
    ref = img * t[:, None, None].astype(np.float64) + light * (
        1 - t[:, None, None].astype(np.float64))
    np.testing.assert_allclose(cube, ref, rtol=1e-6)
    # a float64 light with a float32 image: the sum in float64
    assert scatter(img.astype(np.float32), t[:, None, None],
                   light.astype(np.float64)).dtype == np.float64
    # the caller's arrays are not written
    before = img.copy()
    scatter(img, t[:, None, None], light)
    np.testing.assert_array_equal(img, before)


def test_empty_images():
    for shape in [(0, 4, 3), (4, 0, 3), (0, 0, 3)]:
        img = np.zeros(shape, np.uint8)
        t = transmission(np.zeros(shape[:2]), 0.02)[..., None]
        assert scatter(img, t, np.asarray(ATMOSPHERIC_LIGHT)).shape == shape


def test_recover_inverts_scatter():
    rng = np.random.RandomState(3)
    clear = rng.rand(7, 9, 3)
    t = rng.uniform(0.1, 1, (7, 9, 1))
    light = np.array([0.9, 0.92, 0.95])
    hazy = scatter(clear, t, light)
    np.testing.assert_allclose(recover(hazy, t, light), clear, atol=1e-12)
    # tensors, [B, 3, H, W] with [B, 1, H, W] and [B, 3, 1, 1]
    x = torch.from_numpy(hazy).permute(2, 0, 1)[None]
    tt = torch.from_numpy(t).permute(2, 0, 1)[None]
    a = torch.from_numpy(light).view(1, 3, 1, 1)
    torch.testing.assert_close(
        recover(x, tt, a), torch.from_numpy(clear).permute(2, 0, 1)[None])


@pytest.mark.parametrize('beta, error, match', [
    (-0.01, ValueError, 'finite number >= 0'),
    (float('nan'), ValueError, 'finite'),
    (float('inf'), ValueError, 'finite'),
    ('0.02', TypeError, 'number'),
    (None, TypeError, 'number'),
    (True, TypeError, 'number'),
    ((0.01, 0.02), TypeError, 'number'),
])
def test_bad_beta(beta, error, match):
    with pytest.raises(error, match=match):
        check_beta(beta)
    with pytest.raises(error, match=match):
        transmission(np.ones(3), beta)


def test_check_beta_names_the_caller():
    assert check_beta(np.float32(0.5)) == 0.5
    assert check_beta(0) == 0.0 and isinstance(check_beta(0), float)
    with pytest.raises(ValueError, match='^CBNetAddFog: beta'):
        check_beta(-1, 'CBNetAddFog')


@pytest.mark.parametrize('depth', [np.array([1.0, -0.5]),
                                   np.array([[np.nan, 2.0]])])
def test_bad_distances(depth):
    with pytest.raises(ValueError, match='distances must be >= 0'):
        transmission(depth, 0.02)


@pytest.mark.parametrize('clear, t, light, match', [
    # t per pixel of another image size
    (np.zeros((4, 5, 3)), np.ones((4, 6, 1)), np.ones(3), 'broadcast'),
    # an RGBA light on an RGB image
    (np.zeros((4, 5, 3)), np.ones((4, 5, 1)), np.ones(4), 'broadcast'),
    # a grey H x W image with a per-row [H, 1, 1] t would become H x H x W
    (np.zeros((4, 5)), np.ones((4, 1, 1)), np.ones(1), 'change'),
    (np.zeros((4, 5, 1)), np.ones((4, 5, 1)), np.ones(3), 'change'),
])
def test_wrong_shapes(clear, t, light, match):
    with pytest.raises(ValueError, match=match):
        scatter(clear, t, light)
