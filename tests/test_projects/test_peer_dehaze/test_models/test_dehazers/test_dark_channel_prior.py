"""CBNetDarkChannelPrior against the scattering model and numpy/scipy."""
import math

import pytest
import torch
from mmdet.registry import MODELS

import cbnet_dehaze  # noqa: F401


def psnr(x, y):
    return -10 * math.log10(torch.mean((x - y)**2).item())


#: Rows of sky at the top of the synthetic scene (t = 0 there).
SKY = 12


def synthetic_scene(h=96, w=128, seed=0):
    """A clear image J obeying the dark channel prior, depth, t, A, I.

    J: random colours in 16x16 blocks, each block with one channel at 0.02
    (colourful objects, as the prior assumes), and a sky band of ``SKY``
    rows at the top; depth falls from 60 m below the sky to 5 m at the
    bottom (a road scene), the sky is infinitely far (t = 0: fog only, as
    in Foggy Cityscapes); t = exp(-0.02 * depth), I = J t + A (1 - t).
    """
    g = torch.Generator().manual_seed(seed)
    blocks = torch.rand(1, 3, h // 16, w // 16, generator=g) * 0.8 + 0.1
    clear = torch.nn.functional.interpolate(blocks, size=(h, w),
                                            mode='nearest')
    zero = torch.randint(0, 3, (1, 1, h // 16, w // 16), generator=g)
    zero = torch.nn.functional.interpolate(zero.float(), size=(h, w),
                                           mode='nearest').long()
    clear = clear.scatter(1, zero, 0.02)
    clear[:, :, :SKY] = torch.tensor([0.6, 0.7, 0.85]).view(1, 3, 1, 1)
    depth = torch.linspace(60, 5, h).view(1, 1, h, 1).repeat(1, 1, 1, w)
    trans = torch.exp(-0.02 * depth)
    trans[:, :, :SKY] = 0
    light = torch.tensor([0.9, 0.92, 0.95]).view(1, 3, 1, 1)
    hazy = clear * trans + light * (1 - trans)
    return clear, hazy, trans, light


def test_recovers_clear_image_from_scattering_model():
    """DCP on I = J t + A (1 - t): below the sky (where the prior holds)
    the PSNR to J rises from 10.5 dB (hazy) to 27.8 dB (measured; omega
    0.95 keeps 5% of the haze), asserted > 24 dB."""
    clear, hazy, trans, light = synthetic_scene()
    dcp = MODELS.build(dict(type='CBNetDarkChannelPrior', patch_size=7,
                            guided_radius=8))
    out = dcp(hazy)
    ground = (slice(None), slice(None), slice(SKY, None))
    assert psnr(hazy[ground], clear[ground]) < 12
    assert psnr(out[ground], clear[ground]) > 24
    # the estimated atmospheric light is the true one within 0.02
    est = dcp.atmospheric_light(hazy, dcp.dark_channel(hazy))
    assert (est - light).abs().max() < 0.02
    # and the refined transmission follows the true one below the sky
    t = dcp.transmission(hazy, est)
    assert (t - trans)[ground].abs().mean() < 0.05


def test_atmospheric_light_is_brightest_of_haziest_pixels():
    """He et al.: among the top dark-channel pixels, the brightest input
    pixel (not the one with the highest dark channel)."""
    img = torch.zeros(2, 3, 10, 10)
    img[:, :, 2, 3] = torch.tensor([0.9, 0.9, 0.9])  # dark 0.9, sum 2.7
    img[:, :, 7, 1] = torch.tensor([0.85, 0.99, 0.99])  # dark .85, sum 2.83
    img[1, :, 5, 5] = torch.tensor([0.88, 1.0, 1.0])  # image 1 only
    dcp = MODELS.build(dict(type='CBNetDarkChannelPrior', patch_size=1,
                            top_fraction=0.02))  # the top 2 of 100
    light = dcp.atmospheric_light(img, dcp.dark_channel(img))
    assert light.shape == (2, 3, 1, 1)
    torch.testing.assert_close(light[0].flatten(),
                               torch.tensor([0.85, 0.99, 0.99]))
    torch.testing.assert_close(light[1].flatten(),
                               torch.tensor([0.88, 1.0, 1.0]))


def test_batched_equals_one_by_one_any_size():
    dcp = MODELS.build(dict(type='CBNetDarkChannelPrior'))
    imgs = torch.rand(3, 3, 33, 47)
    batched = dcp(imgs)
    for i in range(3):
        torch.testing.assert_close(batched[i:i + 1], dcp(imgs[i:i + 1]))
    for shape in [(1, 3, 1, 1), (1, 3, 5, 3), (2, 1, 20, 31)]:
        out = dcp(torch.rand(shape))
        assert out.shape == (shape[0], 3) + shape[2:]
        assert torch.isfinite(out).all()


def test_white_black_frames_and_bad_input():
    dcp = MODELS.build(dict(type='CBNetDarkChannelPrior'))
    for value in (0.0, 1.0):
        out = dcp(torch.full((2, 3, 40, 30), value))
        assert torch.isfinite(out).all()
        # a uniform frame stays uniform (no haze to remove, nothing to add)
        torch.testing.assert_close(out, torch.full_like(out, value))
    with pytest.raises(ValueError, match='RGBA'):
        dcp(torch.rand(1, 4, 8, 8))
    with pytest.raises(ValueError, match='odd'):
        MODELS.build(dict(type='CBNetDarkChannelPrior', patch_size=4))


@pytest.mark.skipif(not torch.cuda.is_available(), reason='needs CUDA')
def test_cuda_matches_cpu():
    _, hazy, _, _ = synthetic_scene()
    dcp = MODELS.build(dict(type='CBNetDarkChannelPrior'))
    torch.testing.assert_close(dcp(hazy.cuda()).cpu(), dcp(hazy),
                               atol=1e-4, rtol=0)
