"""The dark channel prior's filters against numpy/scipy."""
import numpy as np
import pytest
import torch
from scipy import ndimage

from cbnet_dehaze.models.dehazers.dark_channel import (box_mean, guided_filter,
                                                       min_filter)


def numpy_box_mean(x, r):
    h, w = x.shape
    out = np.zeros_like(x)
    for i in range(h):
        for j in range(w):
            out[i, j] = x[max(0, i - r):i + r + 1,
                          max(0, j - r):j + r + 1].mean()
    return out


@pytest.mark.parametrize('radius', [0, 2, 12])
def test_box_mean_matches_clipped_window_mean(radius):
    x = np.random.RandomState(radius).rand(7, 9)
    got = box_mean(torch.from_numpy(x)[None, None], radius)[0, 0].numpy()
    np.testing.assert_allclose(got, numpy_box_mean(x, radius), atol=1e-12)


@pytest.mark.parametrize('size', [1, 3, 5, 7, 15, 31])
def test_min_filter_matches_scipy(size):
    """Exactly, at every window side (powers of two and between them), on
    images smaller and larger than the window."""
    for k, shape in enumerate([(2, 3, 11, 6), (1, 1, 1, 1), (1, 1, 5, 40),
                               (3, 1, 40, 33)]):
        x = np.random.RandomState(size + k).rand(*shape).astype(np.float32)
        got = min_filter(torch.from_numpy(x), size).numpy()
        ref = ndimage.minimum_filter(x, size=(1, 1, size, size),
                                     mode='nearest')
        np.testing.assert_array_equal(got, ref)


def test_guided_filter_matches_numpy_rederivation():
    """He et al. 2010, Algorithm 1, with a brute-force box filter."""
    rng = np.random.RandomState(0)
    guide, src = rng.rand(9, 12), rng.rand(9, 12)
    r, eps = 3, 1e-2
    f = lambda x: numpy_box_mean(x, r)  # noqa: E731
    mean_i, mean_p = f(guide), f(src)
    a = (f(guide * src) - mean_i * mean_p) / (
        f(guide * guide) - mean_i**2 + eps)
    b = mean_p - a * mean_i
    ref = f(a) * guide + f(b)
    t = lambda x: torch.from_numpy(x)[None, None]  # noqa: E731
    got = guided_filter(t(guide), t(src), r, eps)[0, 0].numpy()
    np.testing.assert_allclose(got, ref, atol=1e-10)
