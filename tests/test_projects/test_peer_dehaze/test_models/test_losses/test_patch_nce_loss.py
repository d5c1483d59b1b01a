"""PatchNCE against a numpy re-derivation of InfoNCE."""
import numpy as np
import pytest
import torch
from mmdet.registry import MODELS

import cbnet_dehaze  # noqa: F401
from cbnet_dehaze.models.losses.patch_nce_loss import patch_nce


def numpy_patch_nce(q, k, tau):
    losses = []
    for qb, kb in zip(q, k):
        qb = qb / np.linalg.norm(qb, axis=1, keepdims=True)
        kb = kb / np.linalg.norm(kb, axis=1, keepdims=True)
        logits = qb @ kb.T / tau
        for i in range(len(qb)):
            row = logits[i] - logits[i].max()
            losses.append(-(row[i] - np.log(np.exp(row).sum())))
    return float(np.mean(losses))


def test_matches_numpy():
    rng = np.random.RandomState(0)
    q, k = rng.randn(2, 5, 4), rng.randn(2, 5, 4)
    got = patch_nce(torch.from_numpy(q), torch.from_numpy(k), tau=0.2)
    assert got.item() == pytest.approx(numpy_patch_nce(q, k, 0.2), rel=1e-9)
    # matching patches: the positive wins, loss far below log(N)
    aligned = patch_nce(torch.from_numpy(q), torch.from_numpy(q), tau=0.07)
    assert aligned.item() < 0.1 * np.log(5)
    assert patch_nce(torch.zeros(0, 3, 4), torch.zeros(0, 3, 4)).item() == 0
    with pytest.raises(ValueError, match='one shape'):
        patch_nce(torch.zeros(1, 3, 4), torch.zeros(1, 2, 4))


def test_module_over_layers():
    loss = MODELS.build(dict(type='CBNetPatchNCELoss', in_channels=[4, 6],
                             num_patches=10, proj_channels=8))
    feats = [torch.randn(2, 4, 5, 5), torch.randn(2, 6, 3, 3)]
    value = loss(feats, [f.clone() for f in feats])
    assert value.ndim == 0 and torch.isfinite(value)
    value.backward()
    assert all(p.grad is not None for p in loss.parameters())
    with pytest.raises(ValueError, match='2 feature layers'):
        loss(feats[:1], feats[:1])
