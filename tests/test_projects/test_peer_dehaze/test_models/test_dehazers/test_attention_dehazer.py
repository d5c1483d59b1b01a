"""CBNetAttentionDehazer: shapes, bad input, residual identity, learning."""
import pytest
import torch
from mmdet.registry import MODELS
from torch import nn

import cbnet_dehaze  # noqa: F401
from cbnet_dehaze.models.dehazers.attention_conv_block import (
    ChannelAttentionBranch, WindowAttentionBranch)


def build(**kwargs):
    torch.manual_seed(0)
    return MODELS.build(dict(type='CBNetAttentionDehazer', **kwargs))


def perturbed(**kwargs):
    """A dehazer whose tail is not zero (no longer the identity)."""
    model = build(**kwargs)
    nn.init.normal_(model.tail.weight, std=0.05)
    return model


@pytest.mark.parametrize('shape', [(1, 3, 37, 53), (2, 3, 8, 8),
                                   (1, 3, 1, 1), (3, 3, 17, 9)])
def test_shapes_and_range_any_size(shape):
    model = perturbed().eval()
    img = torch.rand(shape)
    out = model(img)
    assert out.shape == shape
    assert torch.isfinite(out).all()
    assert out.min() >= 0 and out.max() <= 1
    # the tail is not zero: the output is not the input
    assert not torch.allclose(out, img)


def test_untrained_is_identity_residual():
    """Zero-initialised tail + residual learning: J = I exactly."""
    model = build().eval()
    img = torch.rand(2, 3, 21, 34)
    assert torch.equal(model(img), img)
    # and the correction is what the tail predicts, added to the input
    model = perturbed().eval()
    with torch.no_grad():
        corr = model.tail(model.features(img)[-1])
    torch.testing.assert_close(model(img), (img + corr).clamp(0, 1))


def test_empty_batch_and_extreme_frames():
    model = perturbed().eval()
    assert model(torch.rand(0, 3, 16, 16)).shape == (0, 3, 16, 16)
    for value in (0.0, 1.0):
        out = model(torch.full((1, 3, 24, 40), value))
        assert torch.isfinite(out).all()


def test_grey_converted_rgba_and_bad_values_refused():
    model = perturbed().eval()
    grey = torch.rand(1, 1, 12, 12)
    torch.testing.assert_close(model(grey),
                               model(grey.expand(-1, 3, -1, -1)))
    with pytest.raises(ValueError, match='RGBA'):
        model(torch.rand(1, 4, 12, 12))
    with pytest.raises(ValueError, match='channels'):
        model(torch.rand(1, 2, 12, 12))
    with pytest.raises(ValueError, match=r'\[0, 1\]'):
        model(torch.rand(1, 3, 12, 12) * 255)
    with pytest.raises(ValueError, match='NaN'):
        model(torch.full((1, 3, 4, 4), float('nan')))
    with pytest.raises(TypeError, match='float'):
        model(torch.zeros(1, 3, 4, 4, dtype=torch.uint8))
    with pytest.raises(ValueError, match='empty'):
        model(torch.rand(1, 3, 0, 5))


def test_paper_design():
    """Leaky ReLU 0.01 everywhere, both branches, sizes configurable."""
    model = build(channels=8, num_blocks=3, num_heads=4, window_size=4)
    acts = [m for m in model.modules()
            if isinstance(m, (nn.ReLU, nn.LeakyReLU, nn.GELU))]
    assert acts and all(
        isinstance(m, nn.LeakyReLU) and m.negative_slope == 0.01
        for m in acts)
    assert len(model.blocks) == 3
    for block in model.blocks:
        assert isinstance(block.cab, ChannelAttentionBranch)
        assert isinstance(block.swmsa, WindowAttentionBranch)
        assert block.swmsa.window.w_msa.window_size == (4, 4)
        assert block.swmsa.shifted.shift_size == 2
    small = sum(p.numel() for p in build().parameters())
    large = sum(p.numel() for p in build(channels=32).parameters())
    assert large > 2 * small
    with pytest.raises(ValueError, match='divisible'):
        build(channels=10, num_heads=4)


def test_channel_attention_branch_reference():
    """CAB = x * sigmoid(MLP(GAP(convs(x)))), re-derived with F ops."""
    torch.manual_seed(1)
    cab = ChannelAttentionBranch(8, reduction=2)
    x = torch.randn(2, 8, 9, 11)
    f = torch.nn.functional
    c1, c2 = cab.convs[0][0], cab.convs[1][0]
    y = f.leaky_relu(f.conv2d(x, c1.weight, c1.bias, padding=1), 0.01)
    y = f.leaky_relu(f.conv2d(y, c2.weight, c2.bias, padding=1), 0.01)
    g = y.mean((2, 3), keepdim=True)
    w1, w2 = cab.weights[1][0], cab.weights[2]
    g = f.leaky_relu(f.conv2d(g, w1.weight, w1.bias), 0.01)
    ref = x * torch.sigmoid(f.conv2d(g, w2.weight, w2.bias))
    torch.testing.assert_close(cab(x), ref)


def test_window_branch_sums_window_and_shifted_attention():
    torch.manual_seed(2)
    branch = WindowAttentionBranch(8, num_heads=2, window_size=4)
    x = torch.randn(1, 8, 10, 7)  # not a multiple of the window
    tokens = branch.norm(x.flatten(2).transpose(1, 2))
    ref = branch.window(tokens, (10, 7)) + branch.shifted(tokens, (10, 7))
    ref = branch.proj(ref.transpose(1, 2).reshape(1, 8, 10, 7))
    torch.testing.assert_close(branch(x), ref)
    # the shifted windows see other neighbourhoods than the plain ones
    assert not torch.allclose(branch.window(tokens, (10, 7)),
                              branch.shifted(tokens, (10, 7)))


def test_learns_to_remove_synthetic_haze():
    """A few Adam steps on I = J t + A (1 - t) reduce the L1 to J."""
    torch.manual_seed(3)
    clear = torch.rand(2, 3, 16, 16)
    hazy = clear * 0.6 + 0.4 * 0.9
    model = build(channels=8, num_blocks=1)
    opt = torch.optim.Adam(model.parameters(), lr=1e-2)
    start = (model(hazy) - clear).abs().mean().item()
    for _ in range(30):
        loss = (model(hazy) - clear).abs().mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.5 * start
    # every parameter got a gradient
    assert all(p.grad is not None for p in model.parameters())
