"""Tests of the NAS-FPN adapter neck (``CBNetNASFPN``)."""
import math

import pytest
import torch
import torch.nn.functional as F
from mmdet.models.necks import NASFPN
from mmdet.registry import MODELS

import cbnet_mmdet  # noqa: F401  (registers the components)

MIT_B0 = [32, 64, 160, 256]
MIT_B5 = [64, 128, 320, 512]
IN_STRIDES = (4, 8, 16, 32)


def mit_like_feats(channels, img_hw, batch=1, seed=0):
    """Random maps with MiT's sizes: ceil(H / s) x ceil(W / s)."""
    g = torch.Generator().manual_seed(seed)
    h, w = img_hw
    return [
        torch.randn(batch, c, math.ceil(h / s), math.ceil(w / s), generator=g)
        for c, s in zip(channels, IN_STRIDES)
    ]


def build(**kwargs):
    cfg = dict(type='CBNetNASFPN', in_channels=MIT_B0, out_channels=16,
               stack_times=1, init_cfg=None)
    cfg.update(kwargs)
    return MODELS.build(cfg)


@pytest.mark.parametrize('channels', [MIT_B0, MIT_B5], ids=['B0', 'B5'])
@pytest.mark.parametrize('img_hw', [(64, 96), (97, 75), (33, 17), (5, 3)])
def test_shapes_and_strides(channels, img_hw):
    neck = build(in_channels=channels, stack_times=2)
    outs = neck(mit_like_feats(channels, img_hw, batch=2))
    strides = (4, 8, 16, 32, 64)
    assert len(outs) == len(strides)
    for out, s in zip(outs, strides):
        assert out.shape == (2, 16, math.ceil(img_hw[0] / s),
                             math.ceil(img_hw[1] / s))
        assert torch.isfinite(out).all()


def test_default_width_is_256():
    neck = MODELS.build(
        dict(type='CBNetNASFPN', in_channels=MIT_B5, stack_times=1))
    outs = neck(mit_like_feats(MIT_B5, (32, 32)))
    assert [o.shape[1] for o in outs] == [256] * 5
    assert neck.stack_times == 1 and len(neck.fpn_stages) == 1


@pytest.mark.parametrize('num_outs,start_level,strides', [
    (6, 0, (4, 8, 16, 32, 64, 128)),
    (5, 1, (8, 16, 32, 64, 128)),
    (7, 1, (8, 16, 32, 64, 128, 256, 512)),
])
def test_configurable_levels(num_outs, start_level, strides):
    img_hw = (99, 130)
    neck = build(num_outs=num_outs, start_level=start_level)
    outs = neck(mit_like_feats(MIT_B0, img_hw))
    assert [tuple(o.shape[-2:]) for o in outs] == [
        (math.ceil(img_hw[0] / s), math.ceil(img_hw[1] / s)) for s in strides
    ]


def test_same_graph_as_mmdet_nasfpn_on_even_sizes():
    """On sizes where floor == ceil the neck is exactly MMDet's NASFPN."""
    torch.manual_seed(0)
    ours = build(stack_times=2, init_cfg=None)
    ref = NASFPN(MIT_B0, 16, num_outs=5, stack_times=2, init_cfg=None)
    ref.load_state_dict(ours.state_dict())
    feats = mit_like_feats(MIT_B0, (128, 192))
    # ours runs NHWC on CPU: another oneDNN algorithm, float rounding
    for a, b in zip(ours(feats), ref(feats)):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-4)
    ours.channels_last = False  # NCHW: the very same arithmetic
    for a, b in zip(ours(feats), ref(feats)):
        torch.testing.assert_close(a, b)


def test_no_stack_is_lateral_projection_and_pooling():
    """stack_times=0: 1x1 projections plus a ceil-mode pooled extra level,
    checked against a hand computation."""
    neck = build(stack_times=0)
    feats = mit_like_feats(MIT_B0, (70, 100))  # 3x4 at stride 32
    outs = neck(feats)
    for x, conv, out in zip(feats, neck.lateral_convs, outs):
        w = conv.conv.weight[:, :, 0, 0]
        expected = torch.einsum('oc,bchw->bohw', w, x) + \
            conv.conv.bias[None, :, None, None]
        torch.testing.assert_close(out, expected)
    extra = neck.extra_downsamples[0][0].conv
    last = F.conv2d(outs[3], extra.weight, extra.bias)
    padded = F.pad(last, (0, 0, 0, 1), value=float('-inf'))  # 3x4 -> 4x4
    expected = padded.unfold(2, 2, 2).unfold(3, 2, 2).amax((-1, -2))
    torch.testing.assert_close(outs[4], expected)


def test_upsample_mode_is_used_by_cells():
    feats = mit_like_feats(MIT_B0, (64, 64))
    torch.manual_seed(0)
    nearest = build(upsample_mode='nearest')
    bilinear = build(upsample_mode='bilinear')
    bilinear.load_state_dict(nearest.state_dict())
    assert all(c.upsample_mode == 'bilinear'
               for st in bilinear.fpn_stages for c in st.values())
    out_n, out_b = nearest(feats), bilinear(feats)
    assert not torch.allclose(out_n[0], out_b[0])


def test_gradients_reach_every_input():
    feats = [f.requires_grad_() for f in mit_like_feats(MIT_B5, (37, 41))]
    neck = build(in_channels=MIT_B5)
    sum(o.sum() for o in neck(feats)).backward()
    for f in feats:
        assert f.grad is not None and f.grad.abs().sum() > 0


@pytest.mark.parametrize('kwargs,match', [
    (dict(num_outs=4), 'num_outs=4'),
    (dict(upsample_mode='bicubic'), 'upsample_mode'),
    (dict(start_level=4), 'start_level=4'),
    (dict(in_channels=[8, 8, 8, 8, 8, 8]), 'more than'),
    (dict(end_level=2), 'end_level=2'),
    (dict(fine_path='fast'), 'fine_path'),
    (dict(fine_path='light', start_level=3), 'needs a backbone level'),
])
def test_bad_config(kwargs, match):
    with pytest.raises(ValueError, match=match):
        build(**kwargs)


def test_bad_input():
    neck = build()
    feats = mit_like_feats(MIT_B0, (32, 32))
    with pytest.raises(ValueError, match='expected 4 input maps'):
        neck(feats[:3])
    with pytest.raises(ValueError, match='do not match'):
        neck(mit_like_feats(MIT_B5, (32, 32)))


@pytest.mark.parametrize('img_hw', [(67, 45), (64, 96)])
def test_on_mit_b0_outputs(img_hw):
    """End to end on the real backbone: MiT-B0 maps, ceil(H / s) levels."""
    torch.manual_seed(0)
    backbone = MODELS.build(dict(type='CBNetMiT', arch='b0', init_cfg=None))
    neck = build(in_channels=backbone.out_channels)
    with torch.no_grad():
        outs = neck(backbone(torch.randn(1, 3, *img_hw)))
    assert [tuple(o.shape[-2:]) for o in outs] == [
        (math.ceil(img_hw[0] / s), math.ceil(img_hw[1] / s))
        for s in (4, 8, 16, 32, 64)
    ]


@pytest.mark.parametrize('img_hw', [(64, 96), (97, 75)])
def test_channels_last_is_the_same_function(img_hw):
    """The CPU inference default (channels_last cells) computes what NCHW
    does, and hands contiguous NCHW maps to the heads (mmcv's RoIAlign and
    deformable convolution read raw NCHW memory)."""
    torch.manual_seed(0)
    fast = build(stack_times=2, num_outs=6)
    plain = build(stack_times=2, num_outs=6, channels_last=False)
    plain.load_state_dict(fast.state_dict())
    feats = mit_like_feats(MIT_B0, img_hw)
    with torch.no_grad():
        outs = fast(feats)
    assert all(o.is_contiguous() for o in outs)
    for a, b in zip(outs, plain(feats)):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-4)


@pytest.mark.parametrize('img_hw', [(64, 96), (97, 75), (5, 3)])
@pytest.mark.parametrize('num_outs', [5, 6])
def test_light_fine_path_keeps_levels(img_hw, num_outs):
    neck = build(fine_path='light', num_outs=num_outs, stack_times=2)
    outs = neck(mit_like_feats(MIT_B0, img_hw, batch=2))
    assert [tuple(o.shape) for o in outs] == [
        (2, 16, math.ceil(img_hw[0] / s), math.ceil(img_hw[1] / s))
        for s in (4, 8, 16, 32, 64, 128)[:num_outs]
    ]
    assert all(torch.isfinite(o).all() and o.is_contiguous() for o in outs)


def test_light_fine_path_is_nasfpn_from_stride_8_plus_fpn_level():
    """Reference: MMDet's NASFPN on the three coarser MiT maps (P3-P7 at
    strides 8-128) and, at stride 4, FPN's top-down step: lateral 1x1 of the
    finest map + nearest-upsampled stride-8 output, then a 3x3 conv."""
    torch.manual_seed(0)
    neck = build(fine_path='light', stack_times=2, channels_last=False)
    ref = NASFPN(in_channels=MIT_B0, out_channels=16, num_outs=5,
                 stack_times=2, start_level=1)
    ref.load_state_dict(
        {k: v for k, v in neck.state_dict().items()
         if not k.startswith('fine_')})
    img_hw = (128, 256)  # even sizes: MMDet floors where we ceil
    feats = mit_like_feats(MIT_B0, img_hw)
    with torch.no_grad():
        outs = neck(feats)
        want = list(ref(feats))
        fine = neck.fine_lateral.conv(feats[0]) + F.interpolate(
            want[0], scale_factor=2, mode='nearest')
        fine = F.conv2d(fine, neck.fine_conv.conv.weight,
                        neck.fine_conv.conv.bias, padding=1)
    torch.testing.assert_close(outs[0], fine, rtol=1e-5, atol=1e-5)
    for got, exp in zip(outs[1:], want[:4]):
        torch.testing.assert_close(got, exp, rtol=1e-5, atol=1e-5)


def test_light_fine_path_has_no_cells_at_stride_4():
    """The point of the light path: no merging cell runs at the finest
    level, so it costs a fraction of the default's multiply-adds."""
    from mmengine.analysis import FlopAnalyzer
    feats = tuple(mit_like_feats(MIT_B5, (128, 256)))
    flops = {}
    for fine_path in ('cells', 'light'):
        neck = build(in_channels=MIT_B5, out_channels=64, stack_times=3,
                     fine_path=fine_path, channels_last=False).eval()
        flops[fine_path] = FlopAnalyzer(neck, (feats, )).total()
    assert flops['light'] < 0.5 * flops['cells']  # measured 0.45


def test_light_fine_path_gradients_reach_every_input():
    neck = build(fine_path='light')
    feats = [f.requires_grad_() for f in mit_like_feats(MIT_B0, (64, 64))]
    sum(o.sum() for o in neck(feats)).backward()
    assert all(f.grad is not None and f.grad.abs().sum() > 0 for f in feats)
