"""CBNetMiT: shapes, arch handling, CSPE, freezing, sizes, mmseg parity."""
import pytest
import torch
import torch.nn as nn
from mmdet.registry import MODELS

# the reference of the equality test: mmsegmentation is a pinned test
# requirement (requirements/tests.txt), so a missing reference fails (an
# import error), never skips; imported at collection, as its import
# exports TOKENIZERS_PARALLELISM
from mmseg.models.backbones import mit as mmseg_mit

import cbnet_mmdet  # noqa: F401  (registers CBNetMiT)
from cbnet_mmdet.models.backbones import CBNetMiT
from cbnet_mmdet.models.layers import CBNetMish

TINY = dict(
    embed_dims=[8, 16, 24, 32],
    depths=[1, 2, 1, 1],
    num_heads=[1, 2, 3, 4],
    sr_ratios=[8, 4, 2, 1])


def build(**kwargs):
    cfg = dict(type='CBNetMiT', arch=TINY, drop_path_rate=0., init_cfg=None)
    cfg.update(kwargs)
    model = MODELS.build(cfg)
    model.init_weights()
    return model


def randomise_cspe(model):
    for name, p in model.named_parameters():
        if name.endswith('cspe.table'):
            nn.init.normal_(p, std=0.5)


def test_registered_and_outputs_strides():
    model = build()
    assert isinstance(model, CBNetMiT)
    assert model.out_channels == [8, 16, 24, 32]
    assert model.out_strides == [4, 8, 16, 32]
    outs = model(torch.randn(2, 3, 64, 96))
    assert [tuple(o.shape) for o in outs] == [(2, 8, 16, 24), (2, 16, 8, 12),
                                              (2, 24, 4, 6), (2, 32, 2, 3)]
    sub = build(out_indices=(1, 3))
    assert sub.out_channels == [16, 32] and sub.out_strides == [8, 32]
    assert [o.shape[1] for o in sub(torch.randn(1, 3, 64, 64))] == [16, 32]


def test_named_archs_and_errors():
    b0 = CBNetMiT(arch='B0', init_cfg=None)
    assert b0.embed_dims == [32, 64, 160, 256]
    assert [len(s[1]) for s in b0.layers] == [2, 2, 2, 2]
    assert CBNetMiT._parse_arch('b3')['depths'] == [3, 4, 18, 3]
    with pytest.raises(ValueError, match=r"unknown arch 'b9'.*'b0'.*'b5'"):
        CBNetMiT(arch='b9')
    with pytest.raises(ValueError, match='missing keys'):
        CBNetMiT(arch=dict(embed_dims=[8], depths=[1]))
    with pytest.raises(ValueError, match='unknown keys'):
        CBNetMiT(arch={**TINY, 'widths': [1, 2, 3, 4]})
    with pytest.raises(ValueError, match='one value per stage'):
        CBNetMiT(arch={**TINY, 'depths': [1, 1, 1]})
    with pytest.raises(ValueError, match='divisible'):
        CBNetMiT(arch={**TINY, 'num_heads': [3, 2, 3, 4]})
    with pytest.raises(TypeError, match='arch'):
        CBNetMiT(arch=3)
    with pytest.raises(ValueError, match='pos_encoding'):
        CBNetMiT(arch=TINY, pos_encoding='ape')
    with pytest.raises(ValueError, match='out_indices'):
        CBNetMiT(arch=TINY, out_indices=(4, ))
    with pytest.raises(ValueError, match='frozen_stages'):
        CBNetMiT(arch=TINY, frozen_stages=5)


def test_bad_inputs():
    model = build()
    with pytest.raises(ValueError, match='at least 29x29'):
        model(torch.randn(1, 3, 16, 64))
    with pytest.raises(ValueError, match=r'Tensor\[B, C, H, W\]'):
        model(torch.randn(3, 64, 64))
    # empty batch: same shapes as a real forward, batch 0
    full = [o.shape[1:] for o in model(torch.randn(1, 3, 61, 97))]
    empty = model(torch.randn(0, 3, 61, 97))
    assert [o.shape[0] for o in empty] == [0] * 4
    assert [o.shape[1:] for o in empty] == full


def test_activation_and_drop_path():
    model = build(drop_path_rate=0.3)
    ffn_acts = [m.ffn.layers[2] for s in model.layers for m in s[1]]
    assert all(isinstance(a, CBNetMish) for a in ffn_acts)
    torch_mish = build(act_cfg=dict(type=nn.Mish))
    assert isinstance(torch_mish.layers[0][1][0].ffn.layers[2], nn.Mish)
    gelu = build(act_cfg=dict(type='GELU'))
    assert isinstance(gelu.layers[0][1][0].ffn.layers[2], nn.GELU)
    rates = [m.ffn.dropout_layer.drop_prob for s in model.layers for m in s[1]]
    assert rates[0] == 0 and rates[-1] == pytest.approx(0.3)
    assert rates == sorted(rates) and len(rates) == 5


def test_cspe_tables_exist_only_with_cspe():
    cspe, ope = build(), build(pos_encoding='ope')
    tables = [n for n, _ in cspe.named_parameters() if 'cspe' in n]
    assert len(tables) == 5 and not [
        n for n, _ in ope.named_parameters() if 'cspe' in n
    ]
    assert cspe.layers[2][1][0].attn.cspe.table.shape == (3, 225, 8)
    custom = build(cspe_cfg=dict(beta=4, gamma=16))
    assert custom.layers[0][1][0].attn.cspe.table.shape == (1, 81, 8)


@pytest.mark.parametrize('size', [(29, 29), (64, 64), (61, 97), (45, 128)])
def test_cspe_any_size_and_reduces_to_ope(size):
    """Zero tables == OPE with the same weights; non-zero tables differ.

    At 29x29 every stage attends to a single reduced key (softmax of one
    logit), so no position term can change anything there.
    """
    torch.manual_seed(1)
    ope = build(pos_encoding='ope').eval()
    cspe = build().eval()
    missing = cspe.load_state_dict(ope.state_dict(), strict=False)
    assert all(k.endswith('cspe.table') for k in missing.missing_keys)
    x = torch.randn(2, 3, *size)
    h, w = size
    with torch.no_grad():
        ref, out = ope(x), cspe(x)
        assert out[0].shape[2:] == ((h + 3) // 4, (w + 3) // 4)
        for a, b in zip(ref, out):
            torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-5)
        randomise_cspe(cspe)
        changed = cspe(x)
    diffs = [(a - b).abs().max().item() for a, b in zip(ref, changed)]
    if size == (29, 29):
        assert max(diffs) < 1e-5
    else:
        assert min(diffs) > 1e-3


@pytest.mark.parametrize('size', [(64, 64), (61, 97)])
def test_cspe_gradients_reach_every_table(size):
    """Every stage has >= 2 reduced keys at these sizes (see above)."""
    torch.manual_seed(2)
    model = build().train()
    outs = model(torch.randn(2, 3, *size))
    sum(o.pow(2).mean() for o in outs).backward()
    grads = {
        n: p.grad
        for n, p in model.named_parameters() if n.endswith('cspe.table')
    }
    assert len(grads) == 5
    for name, grad in grads.items():
        assert grad is not None and grad.abs().sum() > 0, name


def test_frozen_stages_and_norm_eval():
    model = build(frozen_stages=2, drop_path_rate=0.2)
    model.train()
    for i, stage in enumerate(model.layers):
        frozen = i < 2
        assert all(p.requires_grad != frozen for p in stage.parameters())
        assert all(m.training != frozen for m in stage.modules())
    free = build(frozen_stages=-1)
    assert all(p.requires_grad for p in free.parameters())
    # norm_eval keeps any BatchNorm (none by default) in eval mode
    model = build(norm_eval=True)
    model.layers[3][2] = nn.BatchNorm1d(32)
    model.train()
    assert not model.layers[3][2].training and model.layers[3][1].training


# Published SegFormer encoder sizes (Xie et al. 2021, Table 1 / 6), in M.
PUBLISHED = dict(b0=3.3, b1=13.2, b2=24.2, b3=44.0, b4=60.8, b5=81.4)
# Our exact counts (ope), golden values.
OURS = dict(
    b0=3_319_392,
    b1=13_151_424,
    b2=24_196_288,
    b3=44_072_128,
    b4=60_842_688,
    b5=81_443_008)


@pytest.mark.parametrize('arch', sorted(PUBLISHED))
def test_parameter_counts_match_segformer(arch):
    with torch.device('meta'):  # no memory, no init: B5 is 81M params
        model = CBNetMiT(arch=arch, pos_encoding='ope', init_cfg=None)
    count = sum(p.numel() for p in model.parameters())
    assert count == OURS[arch]
    assert count / 1e6 == pytest.approx(PUBLISHED[arch], rel=0.01)
    with torch.device('meta'):
        cspe = CBNetMiT(arch=arch, pos_encoding='cspe', init_cfg=None)
    tables = sum(p.numel() for n, p in cspe.named_parameters()
                 if n.endswith('cspe.table'))
    dims = sum(d * n for d, n in zip(model.embed_dims, model.arch['depths']))
    assert tables == 225 * dims
    assert sum(p.numel() for p in cspe.parameters()) == count + tables


@pytest.mark.parametrize('arch,size', [('b0', (64, 96)), ('b2', (64, 64))])
def test_equals_mmseg_mix_vision_transformer(arch, size, tmp_path):
    """GELU + ope gives mmsegmentation's MiT outputs for the same weights.

    The reference is initialised randomly, saved in its own layout and
    loaded through ``init_cfg=Pretrained``.
    """
    settings = CBNetMiT._parse_arch(arch)
    torch.manual_seed(3)
    ref = mmseg_mit.MixVisionTransformer(
        embed_dims=settings['embed_dims'][0],
        num_layers=settings['depths'],
        num_heads=settings['num_heads'],
        sr_ratios=settings['sr_ratios'],
        drop_path_rate=0.)
    ref.init_weights()
    for p in ref.parameters():  # move away from zero-bias/unit-norm init
        p.data.add_(torch.randn_like(p) * 0.02)
    ckpt = tmp_path / 'mmseg_mit.pth'
    torch.save(ref.state_dict(), ckpt)
    ours = MODELS.build(
        dict(
            type='CBNetMiT',
            arch=arch,
            act_cfg=dict(type='GELU'),
            pos_encoding='ope',
            init_cfg=dict(type='Pretrained', checkpoint=str(ckpt))))
    ours.init_weights()
    ref.eval(), ours.eval()
    x = torch.randn(2, 3, *size)
    with torch.no_grad():
        expected, got = ref(x), ours(x)
    assert len(got) == len(expected) == 4
    for e, g in zip(expected, got):
        torch.testing.assert_close(g, e, rtol=1e-5, atol=1e-5)


def test_golden_cspe_forward():
    """Fixed seed, CPU: a silent change of the forward logic fails here."""
    torch.manual_seed(0)
    model = build().eval()
    randomise_cspe(model)
    x = torch.randn(1, 3, 64, 80)
    with torch.no_grad():
        outs = model(x)
    corners = [o[0, 0, 0, 0].item() for o in outs]
    assert corners == pytest.approx(
        [0.717755, -1.651206, -0.370387, -1.270246], abs=1e-4)


def test_attn_query_chunk_reaches_every_attention_and_changes_nothing():
    torch.manual_seed(0)
    full = CBNetMiT(arch='b0').eval()
    for blk in full.modules():
        if hasattr(blk, 'cspe') and blk.cspe is not None:
            nn.init.normal_(blk.cspe.table, std=0.5)
    chunked = CBNetMiT(arch='b0', attn_query_chunk=40).eval()
    chunked.load_state_dict(full.state_dict())
    chunks = {m.query_chunk for m in chunked.modules()
              if hasattr(m, 'query_chunk')}
    assert chunks == {40}
    x = torch.randn(1, 3, 96, 160)  # stage 1: 24x40 tokens, 1 row a band
    with torch.no_grad():
        for a, b in zip(full(x), chunked(x)):
            torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-5)
