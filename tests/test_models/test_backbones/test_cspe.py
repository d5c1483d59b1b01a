"""CSPE: bucketing, offsets and the logit term against brute force."""
import math

import pytest
import torch

from cbnet_mmdet.models.backbones.cspe import (ContextualPositionEncoding,
                                               piecewise_bucket,
                                               relative_offsets)


def _bucket_ref(d, alpha=3., beta=7, gamma=32.):
    """Scalar restatement of the docstring's formula."""
    a = abs(d)
    if a <= alpha:
        g = math.floor(a + 0.5)
    else:
        g = math.floor(alpha + math.log(a / alpha) / math.log(gamma / alpha) *
                       (beta - alpha) + 0.5)
        g = min(beta, g)
    return 0 if d == 0 else int(math.copysign(g, d))


def test_piecewise_bucket_golden_and_symmetric():
    d = torch.tensor([0., .5, 1.5, 2.5, 3., 3.5, 5., 10., 20., 31., 32., 1e3])
    expected = [0, 1, 2, 3, 3, 3, 4, 5, 6, 7, 7, 7]
    assert piecewise_bucket(d, 3, 7, 32).tolist() == expected
    assert piecewise_bucket(-d, 3, 7, 32).tolist() == [-e for e in expected]
    dense = torch.linspace(-200, 200, 4001)
    b = piecewise_bucket(dense, 3, 7, 32)
    assert b.dtype == torch.int64
    assert (b.diff() >= 0).all()  # monotonic
    assert b.min() == -7 and b.max() == 7
    assert b.tolist() == [_bucket_ref(x) for x in dense.tolist()]


def test_relative_offsets_use_reduced_key_centres():
    off = relative_offsets(9, 4, 2)
    # key 0 covers query cells 0..3 (centre 1.5), key 1 cells 4..7 (5.5)
    assert off.shape == (9, 2)
    assert off[:, 0].tolist() == [i - 1.5 for i in range(9)]
    assert off[:, 1].tolist() == [i - 5.5 for i in range(9)]
    assert relative_offsets(3, 1, 3).tolist() == [[0, -1, -2], [1, 0, -1],
                                                  [2, 1, 0]]
    assert relative_offsets(0, 2, 0).shape == (0, 0)


@pytest.mark.parametrize('hq,wq,sr', [(9, 7, 4), (8, 8, 8), (5, 3, 1),
                                      (11, 13, 2), (1, 1, 1)])
@pytest.mark.parametrize('heads', [1, 2])  # two gathers / one gather
def test_cspe_term_matches_brute_force(hq, wq, sr, heads):
    torch.manual_seed(0)
    dims = 4
    cspe = ContextualPositionEncoding(heads, dims, alpha=2, beta=4, gamma=9)
    torch.nn.init.normal_(cspe.table)
    hk, wk = hq // sr, wq // sr
    q = torch.randn(3, heads, hq * wq, dims)
    out = cspe(q, (hq, wq), (hk, wk), sr)
    assert out.shape == (3, heads, hq * wq, hk * wk)
    ref = torch.empty_like(out)
    c = (sr - 1) / 2
    for iy in range(hq):
        for ix in range(wq):
            for jy in range(hk):
                for jx in range(wk):
                    by = _bucket_ref(iy - jy * sr - c, 2, 4, 9) + 4
                    bx = _bucket_ref(ix - jx * sr - c, 2, 4, 9) + 4
                    r = cspe.table[:, by * 9 + bx]  # [heads, dims]
                    ref[:, :, iy * wq + ix, jy * wk + jx] = (
                        q[:, :, iy * wq + ix] * r).sum(-1) / math.sqrt(dims)
    torch.testing.assert_close(out, ref, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize('heads', [1, 2])
def test_cspe_empty_batch_and_gradient(heads):
    cspe = ContextualPositionEncoding(heads, 4)
    assert cspe.table.shape == (heads, 15 * 15, 4)
    assert cspe.table.abs().sum() == 0  # zero init: OPE function at start
    out = cspe(torch.randn(0, heads, 12, 4), (3, 4), (1, 2), 2)
    assert out.shape == (0, heads, 12, 2)
    q = torch.randn(1, heads, 12, 4)
    out = cspe(q, (3, 4), (1, 2), 2)
    (out * torch.randn_like(out)).sum().backward()
    used = torch.zeros(15 * 15, dtype=torch.bool)
    by, bx = cspe.bucket_index(3, 1, 2), cspe.bucket_index(4, 2, 2)
    used[(by[:, None, :, None] * 15 + bx[None, :, None, :]).flatten()] = True
    # exactly the buckets that occur receive gradient (zero table or not)
    assert torch.equal(cspe.table.grad.abs().sum((0, 2)) > 0, used)


@pytest.mark.parametrize('kwargs', [
    dict(alpha=0), dict(alpha=8, beta=7), dict(beta=7, gamma=7),
    dict(alpha=1, beta=2.5, gamma=9)
])
def test_cspe_rejects_bad_bucketing(kwargs):
    with pytest.raises(ValueError, match='alpha'):
        ContextualPositionEncoding(1, 4, **kwargs)
