"""``CBNetDeformConv2d`` against mmcv's ``DeformConv2d`` (the reference)."""
import pytest
import torch
from mmcv.ops import DeformConv2d

from cbnet_mmdet.models.layers import CBNetDeformConv2d, deform_conv2d


def pair(in_c=5, out_c=7, k=3, seed=0, **kwargs):
    torch.manual_seed(seed)
    ref = DeformConv2d(in_c, out_c, k, bias=False, **kwargs)
    return ref, CBNetDeformConv2d.from_mmcv(ref)


@pytest.mark.parametrize('kwargs,hw', [
    (dict(padding=1), (9, 13)),
    (dict(padding=0), (8, 6)),
    (dict(padding=2, dilation=2), (7, 11)),
    (dict(padding=1, stride=2), (10, 9)),
    (dict(padding=1), (1, 1)),
])
@pytest.mark.parametrize('scale', [0.0, 0.7, 6.0])
def test_same_as_mmcv(kwargs, hw, scale):
    """Offsets from zero (a plain conv) to far outside the map (the zero
    padding of out-of-range corners)."""
    ref, ours = pair(**kwargs)
    x = torch.randn(2, 5, *hw)
    h_out = (hw[0] + 2 * ref.padding[0] - ref.dilation[0] * 2 - 1) \
        // ref.stride[0] + 1
    w_out = (hw[1] + 2 * ref.padding[1] - ref.dilation[1] * 2 - 1) \
        // ref.stride[1] + 1
    offset = torch.randn(2, 18, h_out, w_out) * scale
    torch.testing.assert_close(ours(x, offset), ref(x, offset),
                               rtol=1e-5, atol=1e-5)


def test_integer_offsets_are_a_shifted_conv():
    """An offset of exactly (1, 0) on every tap is a 3x3 conv one row down,
    a check independent of mmcv."""
    ref, ours = pair(padding=1)
    x = torch.randn(1, 5, 8, 8)
    offset = torch.zeros(1, 18, 8, 8)
    offset[:, 0::2] = 1.0
    want = torch.nn.functional.conv2d(
        torch.nn.functional.pad(x, (1, 1, 0, 2)), ref.weight)
    torch.testing.assert_close(ours(x, offset), want, rtol=1e-5, atol=1e-5)


def test_gradients_match_mmcv():
    ref, ours = pair(padding=1)
    x = torch.randn(2, 5, 6, 7)
    offset = torch.randn(2, 18, 6, 7) * 1.5
    grads = []
    for conv in (ref, ours):
        xi = x.clone().requires_grad_()
        oi = offset.clone().requires_grad_()
        conv.weight.grad = None
        (conv(xi, oi) * torch.linspace(-1, 1, 7)).sum().backward()
        grads.append((xi.grad, oi.grad, conv.weight.grad.clone()))
    for a, b in zip(*grads):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-4)


def test_gradcheck_float64():
    torch.manual_seed(0)
    x = torch.randn(1, 2, 4, 5, dtype=torch.float64, requires_grad=True)
    # offsets away from integer positions (bilinear kinks)
    offset = (torch.rand(1, 18, 4, 5, dtype=torch.float64) * 0.8 + 0.1)
    offset.requires_grad_()
    weight = torch.randn(3, 2, 3, 3, dtype=torch.float64,
                         requires_grad=True)
    assert torch.autograd.gradcheck(
        lambda a, b, c: deform_conv2d(a, b, c, padding=(1, 1)),
        (x, offset, weight))


def test_empty_batch_and_shape_errors():
    _, ours = pair()
    assert ours(torch.randn(0, 5, 4, 4),
                torch.randn(0, 18, 2, 2)).shape == (0, 7, 2, 2)
    # a map smaller than the kernel: no output position
    assert ours(torch.randn(1, 5, 1, 1),
                torch.randn(1, 18, 0, 0)).shape == (1, 7, 0, 0)
    with pytest.raises(ValueError, match='offset must be'):
        ours(torch.randn(1, 5, 4, 4), torch.randn(1, 18, 4, 4))
    with pytest.raises(ValueError, match='expects 5'):
        ours(torch.randn(1, 4, 4, 4), torch.randn(1, 18, 2, 2))


def test_unsupported_mmcv_settings_are_refused():
    with pytest.raises(ValueError, match='groups=1'):
        CBNetDeformConv2d.from_mmcv(
            DeformConv2d(4, 4, 3, deform_groups=2, bias=False))


def test_cascade_rpn_uses_it_with_mmcv_weights():
    """Stage 2 of the CRPN computes the same with either implementation,
    from the same state dict (the parameter key is mmcv's)."""
    from mmdet.registry import MODELS
    heads = {}
    for impl in ('gather', 'mmcv'):
        torch.manual_seed(0)
        heads[impl] = MODELS.build(dict(
            type='CBNetCascadeRPNHead', in_channels=8, feat_channels=8,
            deform_impl=impl)).eval()
    assert isinstance(heads['gather'].stages[1].rpn_conv.conv,
                      CBNetDeformConv2d)
    assert set(heads['gather'].state_dict()) == set(
        heads['mmcv'].state_dict())
    heads['gather'].load_state_dict(heads['mmcv'].state_dict())
    feats = [torch.randn(1, 8, 64 // s, 128 // s)
             for s in (4, 8, 16, 32, 64)]
    offsets = [torch.randn(1, f.shape[2] * f.shape[3], 18) for f in feats]
    with torch.no_grad():
        outs = [heads[i].stages[1](feats, offsets) for i in heads]
    for a, b in zip(*[o[1] for o in outs]):  # objectness per level
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-5)


def test_swapping_draws_no_random_numbers():
    """A model built with either implementation has the same weights
    (the swap shares mmcv's parameter and draws nothing)."""
    from mmdet.registry import MODELS
    states = []
    for impl in ('gather', 'mmcv'):
        torch.manual_seed(0)
        head = MODELS.build(dict(type='CBNetCascadeRPNHead', in_channels=8,
                                 feat_channels=8, deform_impl=impl))
        states.append((head.state_dict(), torch.rand(1)))
    for key, value in states[0][0].items():
        assert torch.equal(value, states[1][0][key]), key
    assert torch.equal(states[0][1], states[1][1])


def test_auto_runs_mmcv_kernel_where_gather_was_not_measured_faster(
        monkeypatch):
    """``impl='auto'`` uses the gather kernel only on the devices of
    ``GATHER_FASTER_ON`` (the CPU): with the CPU taken off that list, the
    CPU stands for a device where it was not measured faster (a GPU), and
    mmcv's kernel must run; ``impl='gather'`` keeps the gather kernel."""
    from cbnet_mmdet.models.layers import cbnet_deform_conv2d as mod
    ref, auto = pair(padding=1)
    forced = CBNetDeformConv2d.from_mmcv(ref, impl='gather')
    x = torch.randn(2, 5, 9, 13)
    offset = torch.randn(2, 18, 9, 13)
    gather_calls = []

    def counted(*args):
        gather_calls.append(1)
        return deform_conv2d(*args)

    monkeypatch.setattr(mod, 'deform_conv2d', counted)
    auto(x, offset)
    assert gather_calls == [1]  # on the CPU: the gather kernel
    monkeypatch.setattr(mod, 'GATHER_FASTER_ON', ())
    out = auto(x, offset)
    assert gather_calls == [1]  # elsewhere: mmcv's
    assert torch.equal(out, ref(x, offset))
    forced(x, offset)
    assert gather_calls == [1, 1]


@pytest.mark.parametrize('n,hw', [(2, (1, 2)), (2, (2, 9)), (33, (4, 5)),
                                  (0, (4, 5))])
def test_auto_where_mmcv_kernel_refuses(monkeypatch, n, hw):
    """Off the gather kernel's devices, maps smaller than the kernel (the
    coarse levels of a small image; mmcv's kernel raises 'input image is
    smaller than kernel', found training the demo CBNet on an H100) go to
    the gather kernel, and a batch that 32 does not divide (mmcv's
    im2col_step) to mmcv's kernel in chunks that do; empty batches too."""
    from cbnet_mmdet.models.layers import cbnet_deform_conv2d as mod
    ref, auto = pair(padding=1)
    forced = CBNetDeformConv2d.from_mmcv(ref, impl='gather')
    monkeypatch.setattr(mod, 'GATHER_FASTER_ON', ())
    x = torch.randn(n, 5, *hw)
    offset = torch.randn(n, 18, *hw)
    torch.testing.assert_close(auto(x, offset), forced(x, offset),
                               rtol=1e-5, atol=1e-5)


def test_impl_is_checked_and_shown():
    with pytest.raises(ValueError, match="'auto' or 'gather'"):
        CBNetDeformConv2d(4, 4, 3, impl='mmcv')
    from mmdet.registry import MODELS
    with pytest.raises(ValueError, match="'auto', 'gather' or 'mmcv'"):
        MODELS.build(dict(type='CBNetCascadeRPNHead', in_channels=8,
                          feat_channels=8, deform_impl='fast'))
    head = MODELS.build(dict(type='CBNetCascadeRPNHead', in_channels=8,
                             feat_channels=8))
    conv = head.stages[1].rpn_conv.conv
    assert isinstance(conv, CBNetDeformConv2d) and conv.impl == 'auto'
    assert "impl='auto'" in repr(conv)


@pytest.mark.skipif(not torch.cuda.is_available(), reason='needs CUDA')
def test_auto_on_cuda_equals_the_gather_kernel():
    ref, auto = pair(padding=1)
    forced = CBNetDeformConv2d.from_mmcv(ref, impl='gather')
    auto, forced = auto.cuda(), forced.cuda()
    x = torch.randn(2, 5, 9, 13, device='cuda')
    offset = torch.randn(2, 18, 9, 13, device='cuda')
    torch.testing.assert_close(auto(x, offset), forced(x, offset),
                               rtol=1e-4, atol=1e-4)
