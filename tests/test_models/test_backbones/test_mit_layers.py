"""CSPESpatialReductionAttention against torch's nn.MultiheadAttention."""
import pytest
import torch
import torch.nn as nn

from cbnet_mmdet.models.backbones.mit_layers import \
    CSPESpatialReductionAttention


def reference(attn, x, hw_shape):
    """Same weights through nn.MultiheadAttention with the CSPE term as its
    float attn_mask (the module's earlier, slower formulation)."""
    mha, c = attn.attn, x.shape[-1]
    if attn.sr_ratio > 1:
        b, n, _ = x.shape
        x_kv = attn.sr(x.transpose(1, 2).reshape(b, c, *hw_shape))
        kv_shape = tuple(x_kv.shape[2:])
        x_kv = attn.norm(x_kv.flatten(2).transpose(1, 2))
    else:
        x_kv, kv_shape = x, hw_shape
    q = nn.functional.linear(x, mha.in_proj_weight[:c], mha.in_proj_bias[:c])
    q = q.view(x.shape[0], x.shape[1], attn.num_heads, -1).transpose(1, 2)
    pos = attn.cspe(q, hw_shape, kv_shape, attn.sr_ratio)
    pos = pos.reshape(-1, x.shape[1], x_kv.shape[1])
    out = mha(query=x.transpose(0, 1), key=x_kv.transpose(0, 1),
              value=x_kv.transpose(0, 1), attn_mask=pos,
              need_weights=False)[0].transpose(0, 1)
    return x + attn.proj_drop(out)


@pytest.mark.parametrize('heads, sr, hw, chunk', [
    (1, 8, (9, 13), None), (2, 4, (8, 8), None), (4, 2, (5, 7), None),
    (2, 1, (3, 4), None),
    # bands of query rows (query_chunk), each with its own rows' CSPE term
    (1, 8, (9, 13), 13),   # one row a band
    (2, 4, (8, 8), 20),    # 2 rows a band
    (4, 2, (5, 7), 15),    # 2 rows, the last band 1 row
    (2, 1, (3, 4), 5),     # 1 row, no spatial reduction
    (1, 2, (6, 5), 3),     # fewer tokens than a row: still one row
    (2, 4, (8, 8), 1000),  # more than the grid: one band
])
def test_matches_multihead_attention_with_float_mask(heads, sr, hw, chunk):
    """Against nn.MultiheadAttention with the whole CSPE term (all queries
    at once): values, and gradients of the input and every parameter."""
    torch.manual_seed(0)
    attn = CSPESpatialReductionAttention(
        16, heads, sr_ratio=sr, cspe_cfg=dict(beta=4, gamma=16),
        query_chunk=chunk)
    nn.init.normal_(attn.cspe.table, std=0.5)
    nn.init.normal_(attn.attn.in_proj_bias, std=0.1)
    x = torch.randn(2, hw[0] * hw[1], 16, requires_grad=True)
    out = attn(x, hw)
    ref = reference(attn, x, hw)
    torch.testing.assert_close(out, ref, rtol=1e-5, atol=1e-5)
    g = torch.randn_like(out)
    params = [x, *attn.parameters()]
    grads = torch.autograd.grad((out * g).sum(), params)
    grads_ref = torch.autograd.grad((ref * g).sum(), params,
                                    allow_unused=True)
    for a, b in zip(grads, grads_ref):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize('chunk', [0, -4, 2.5, '64'])
def test_query_chunk_is_checked(chunk):
    with pytest.raises((ValueError, TypeError), match='query_chunk'):
        CSPESpatialReductionAttention(
            16, 2, sr_ratio=2, cspe_cfg=dict(beta=4, gamma=16),
            query_chunk=chunk)


def test_attention_dropout_only_in_training():
    torch.manual_seed(0)
    attn = CSPESpatialReductionAttention(
        8, 2, attn_drop=0.5, sr_ratio=2, cspe_cfg=dict(beta=4, gamma=16))
    x = torch.randn(1, 16, 8)
    attn.eval()
    torch.testing.assert_close(attn(x, (4, 4)), attn(x, (4, 4)))
    attn.train()
    assert not torch.allclose(attn(x, (4, 4)), attn(x, (4, 4)))


@pytest.mark.parametrize('hw', [(5, 7), (8, 8), (1, 3)])
def test_token_mix_ffn_matches_mmdet_mix_ffn(hw):
    """Same function and gradients as MMDet's NCHW Mix-FFN, same keys."""
    from mmdet.models.backbones.pvt import MixFFN

    from cbnet_mmdet.models.backbones.mit_layers import TokenMixFFN
    torch.manual_seed(0)
    kwargs = dict(embed_dims=8, feedforward_channels=32,
                  act_cfg=dict(type=nn.Mish), use_conv=True)
    ffn, ref = TokenMixFFN(**kwargs), MixFFN(**kwargs)
    ref.load_state_dict(ffn.state_dict())
    assert list(ffn.state_dict()) == list(ref.state_dict())
    x = torch.randn(2, hw[0] * hw[1], 8, requires_grad=True)
    identity = torch.randn(2, hw[0] * hw[1], 8)
    out, expected = ffn(x, hw), ref(x, hw)
    torch.testing.assert_close(out, expected, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(ffn(x, hw, identity), ref(x, hw, identity),
                               rtol=1e-5, atol=1e-5)
    g = torch.randn_like(out)
    grads = torch.autograd.grad((out * g).sum(), [x, *ffn.parameters()])
    grads_ref = torch.autograd.grad((expected * g).sum(),
                                    [x, *ref.parameters()])
    for a, b in zip(grads, grads_ref):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-5)
