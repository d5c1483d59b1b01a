"""The dark channel prior's estimates (cbnet_mmdet/utils/dark_channel.py)
against numpy/scipy: the filters, the dark channel and the atmospheric
light, computed here pixel by pixel, and malformed input refused."""
import numpy as np
import pytest
import torch
from scipy import ndimage

from cbnet_mmdet.utils.dark_channel import (PATCH_SIZE, TOP_FRACTION,
                                            DarkChannelPrior,
                                            atmospheric_light, box_mean,
                                            dark_channel, guided_filter,
                                            min_filter)


def numpy_box_mean(x, r):
    h, w = x.shape
    out = np.zeros_like(x)
    for i in range(h):
        for j in range(w):
            out[i, j] = x[max(0, i - r):i + r + 1,
                          max(0, j - r):j + r + 1].mean()
    return out


def numpy_dark_channel(img, size):
    """``img`` [3, H, W]: the minimum over the channels and the window of
    side ``size`` clipped to the image, pixel by pixel."""
    _, h, w = img.shape
    r = size // 2
    out = np.empty((h, w), img.dtype)
    for i in range(h):
        for j in range(w):
            out[i, j] = img[:, max(0, i - r):i + r + 1,
                            max(0, j - r):j + r + 1].min()
    return out


def test_he_et_al_defaults():
    assert (PATCH_SIZE, TOP_FRACTION) == (15, 0.001)
    dcp = DarkChannelPrior()
    assert (dcp.patch_size, dcp.top_fraction) == (15, 0.001)


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


@pytest.mark.parametrize('size', [1, 3, 15])
@pytest.mark.parametrize('scale', [1.0, 255.0])
def test_dark_channel_against_pixel_loop(size, scale):
    imgs = np.random.RandomState(size).rand(2, 3, 13, 21) * scale
    got = dark_channel(torch.from_numpy(imgs), size)
    assert got.shape == (2, 1, 13, 21) and got.dtype == torch.float64
    for b in range(2):
        np.testing.assert_array_equal(got[b, 0].numpy(),
                                      numpy_dark_channel(imgs[b], size))
    # the method is the function at the prior's window
    dcp = DarkChannelPrior(patch_size=size)
    assert torch.equal(dcp.dark_channel(torch.from_numpy(imgs)), got)


def test_atmospheric_light_without_ties_against_numpy():
    """Window 1 on continuous random values: the top dark-channel pixels
    and the brightest of them are unique, so numpy's argsort gives the same
    pixel. 40 x 50 pixels at 1%: the top 20."""
    imgs = np.random.RandomState(5).rand(3, 3, 40, 50)
    x = torch.from_numpy(imgs)
    got = atmospheric_light(x, dark_channel(x, 1), 0.01)
    assert got.shape == (3, 3) and got.dtype == torch.float64
    for b in range(3):
        dark = imgs[b].min(axis=0).ravel()
        order = np.argsort(dark)[::-1]
        assert dark[order[19]] > dark[order[20]]  # no tie at the cut
        pixels = imgs[b].reshape(3, -1)[:, order[:20]]
        sums = pixels.sum(axis=0)
        assert np.sort(sums)[-1] > np.sort(sums)[-2]
        np.testing.assert_array_equal(got[b].numpy(),
                                      pixels[:, sums.argmax()])


def test_atmospheric_light_at_he_et_als_window():
    """15 px windows make plateaus of equal dark channel values: the pixel
    found has a dark channel at least the 0.1% cut and is at least as
    bright as every pixel strictly above the cut."""
    img = np.random.RandomState(6).randint(0, 256, (1, 3, 60, 90))
    img[0, :, 10:30, 40:70] = np.array([200, 210, 220])[:, None, None]
    x = torch.from_numpy(img.astype(np.float32))
    light = atmospheric_light(x, dark_channel(x)).numpy()[0]
    dark = numpy_dark_channel(img[0], 15).ravel()
    k = int(60 * 90 * 0.001)  # 5
    cut = np.sort(dark)[-k]
    pixels = img[0].reshape(3, -1)
    found = np.flatnonzero((pixels.T == light).all(axis=1))
    assert (dark[found] >= cut).any()
    above = pixels[:, dark > cut]
    assert light.sum() >= (above.sum(axis=0).max() if above.size else 0)
    # here the bright block is the plateau: its colour, on any scale
    np.testing.assert_array_equal(light, [200, 210, 220])
    scaled = atmospheric_light(x / 255, dark_channel(x / 255))
    torch.testing.assert_close(scaled[0], torch.tensor([200, 210, 220.]) /
                               255)


def test_atmospheric_light_keeps_one_pixel_and_the_prior_bounds_it():
    img = torch.zeros(2, 3, 4, 4)
    img[1, :, 2, 2] = torch.tensor([0.3, 0.2, 0.1])
    # 16 pixels at 0.1%: still one searched; all-black: 0 before the bound
    got = atmospheric_light(img, dark_channel(img, 1))
    torch.testing.assert_close(got, torch.tensor([[0., 0, 0],
                                                  [0.3, 0.2, 0.1]]))
    bounded = DarkChannelPrior(patch_size=1).atmospheric_light(
        img, dark_channel(img, 1))
    assert bounded.shape == (2, 3, 1, 1)
    torch.testing.assert_close(bounded.flatten(1),
                               torch.tensor([[0.05, 0.05, 0.05],
                                             [0.3, 0.2, 0.1]]))


@pytest.mark.parametrize('img, error, match', [
    (np.zeros((1, 3, 4, 4)), TypeError, 'Tensor'),
    (torch.zeros(3, 4, 4), ValueError, r'got shape \(3, 4, 4\)'),
    (torch.zeros(1, 4, 4, 4), ValueError, '3 colour channels'),
    (torch.zeros(1, 1, 4, 4), ValueError, '3 colour channels'),
    (torch.zeros(1, 3, 0, 4), ValueError, 'empty'),
    (torch.zeros(1, 3, 4, 0), ValueError, 'empty'),
    (torch.zeros(0, 3, 4, 4), ValueError, 'empty'),
])
def test_malformed_images_refused(img, error, match):
    with pytest.raises(error, match=match):
        dark_channel(img)
    with pytest.raises(error, match=match):
        atmospheric_light(img, torch.zeros(1, 1, 4, 4))


@pytest.mark.parametrize('size', [0, 4, -3, 2.0, True])
def test_bad_patch_size(size):
    with pytest.raises(ValueError, match='odd and positive'):
        dark_channel(torch.zeros(1, 3, 4, 4), size)
    with pytest.raises(ValueError, match='odd and positive'):
        DarkChannelPrior(patch_size=size)


def test_bad_dark_channel_and_fraction():
    img = torch.rand(2, 3, 5, 6)
    with pytest.raises(ValueError, match=r'Tensor\[2, 1, 5, 6\]'):
        atmospheric_light(img, torch.rand(1, 1, 5, 6))
    with pytest.raises(ValueError, match=r'Tensor\[2, 1, 5, 6\]'):
        atmospheric_light(img, img)
    for fraction in (0, 1.5, -0.1):
        with pytest.raises(ValueError, match=r'top_fraction.*\(0, 1\]'):
            atmospheric_light(img, dark_channel(img), fraction)
