"""Tests of ``CBNetExtraLevels``: coarser levels appended to a neck's
outputs (max pooling, no weights), alone and after MMDet's YOLOX PAFPN as
one neck of a list."""
import math

import pytest
import torch
from mmdet.registry import MODELS
from mmengine.registry import init_default_scope

import cbnet_mmdet  # noqa: F401  (registers the components)


def levels(sizes, channels=3, seed=0):
    g = torch.Generator().manual_seed(seed)
    return [torch.randn(2, channels, h, w, generator=g) for h, w in sizes]


@pytest.mark.parametrize('hw', [(8, 12), (7, 5), (1, 1)])
def test_appends_pooled_levels_against_a_numpy_reference(hw):
    neck = MODELS.build(dict(type='CBNetExtraLevels', num_outs=4))
    assert list(neck.parameters()) == [] and neck.state_dict() == {}
    h, w = hw
    ins = levels([(4 * h, 4 * w), (2 * h, 2 * w), (h, w)])
    outs = neck(ins)
    assert len(outs) == 4
    for a, b in zip(outs[:3], ins):
        assert a is b  # the neck's own levels untouched
    # kernel 1, stride 2: every other pixel from the first, ceil(h / 2)
    want = ins[-1].numpy()[:, :, ::2, ::2]
    assert outs[3].shape[-2:] == (math.ceil(h / 2), math.ceil(w / 2))
    torch.testing.assert_close(outs[3], torch.from_numpy(want))


def test_two_extra_levels_and_pass_through():
    ins = levels([(8, 8), (4, 4)])
    outs = MODELS.build(dict(type='CBNetExtraLevels', num_outs=4))(ins)
    assert [o.shape[-1] for o in outs] == [8, 4, 2, 1]
    same = MODELS.build(dict(type='CBNetExtraLevels', num_outs=2))(ins)
    assert same == tuple(ins)


@pytest.mark.parametrize('bad', [0, -1, 2.0, True, None])
def test_bad_num_outs_is_refused(bad):
    with pytest.raises(ValueError, match='num_outs'):
        MODELS.build(dict(type='CBNetExtraLevels', num_outs=bad))


def test_more_levels_in_than_out_or_none_is_refused():
    neck = MODELS.build(dict(type='CBNetExtraLevels', num_outs=2))
    with pytest.raises(ValueError, match='3 levels in'):
        neck(levels([(8, 8), (4, 4), (2, 2)]))
    with pytest.raises(ValueError, match='no levels'):
        neck([])


def test_after_yolox_pafpn_as_a_list_of_necks():
    """A list of neck configs builds as one Sequential: YOLOX's PAFPN
    outputs (strides 8, 16, 32) followed by a pooled stride-64 level."""
    init_default_scope('mmdet')
    neck = MODELS.build([
        dict(type='YOLOXPAFPN', in_channels=[8, 16, 32], out_channels=8,
             num_csp_blocks=1, use_depthwise=True),
        dict(type='CBNetExtraLevels', num_outs=4)])
    neck.eval()
    feats = [torch.randn(1, c, 64 // s, 96 // s)
             for c, s in ((8, 8), (16, 16), (32, 32))]
    with torch.no_grad():
        outs = neck(feats)
        pafpn = neck[0](feats)
    assert [tuple(o.shape[-2:]) for o in outs] == [
        (8, 12), (4, 6), (2, 3), (1, 2)]
    for a, b in zip(outs, pafpn):
        torch.testing.assert_close(a, b)
