"""SSIM against a numpy/scipy re-derivation of Wang et al. (2004)."""
import numpy as np
import pytest
import torch
from mmdet.registry import MODELS
from scipy import ndimage

import cbnet_dehaze  # noqa: F401
from cbnet_dehaze.models.losses.ssim_loss import ssim


def numpy_ssim(x, y, sigma=1.5, radius=5, data_range=1.0):
    """Mean SSIM of two [C, H, W] arrays: scipy Gaussian filtering
    (truncated at ``radius`` pixels), valid region, population variances.
    """
    c1, c2 = (0.01 * data_range)**2, (0.03 * data_range)**2
    vals = []
    for a, b in zip(x.astype(np.float64), y.astype(np.float64)):
        f = lambda t: ndimage.gaussian_filter(  # noqa: E731
            t, sigma, truncate=radius / sigma, mode='constant')
        crop = (slice(radius, -radius), slice(radius, -radius))
        mu_a, mu_b = f(a)[crop], f(b)[crop]
        var_a = f(a * a)[crop] - mu_a**2
        var_b = f(b * b)[crop] - mu_b**2
        cov = f(a * b)[crop] - mu_a * mu_b
        s = ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / (
            (mu_a**2 + mu_b**2 + c1) * (var_a + var_b + c2))
        vals.append(s)
    return float(np.mean(vals))


def test_matches_numpy_rederivation():
    rng = np.random.RandomState(0)
    x = rng.rand(2, 3, 32, 40)
    y = np.clip(x + rng.randn(*x.shape) * 0.1, 0, 1)
    got = ssim(torch.from_numpy(x), torch.from_numpy(y))
    for i in range(2):
        assert got[i].item() == pytest.approx(numpy_ssim(x[i], y[i]),
                                              abs=1e-9)
    # a blurred copy: lower SSIM than a lightly noised one
    blur = ndimage.uniform_filter(x, size=(1, 1, 5, 5))
    assert ssim(torch.from_numpy(x), torch.from_numpy(blur))[0] < got[0]


def test_identity_small_images_and_errors():
    x = torch.rand(1, 3, 20, 20)
    assert ssim(x, x).item() == pytest.approx(1.0, abs=1e-6)
    small = torch.rand(2, 3, 6, 9)  # smaller than the 11-pixel window
    assert torch.isfinite(ssim(small, small.flip(-1))).all()
    with pytest.raises(ValueError, match='one shape'):
        ssim(x, torch.rand(1, 3, 20, 21))


def test_loss_is_weighted_one_minus_ssim():
    loss = MODELS.build(dict(type='CBNetSSIMLoss', loss_weight=0.5))
    x, y = torch.rand(3, 3, 16, 16), torch.rand(3, 3, 16, 16)
    expected = 0.5 * (1 - ssim(x, y)).mean()
    torch.testing.assert_close(loss(x, y), expected)
    assert loss(x[:0], y[:0]).item() == 0
