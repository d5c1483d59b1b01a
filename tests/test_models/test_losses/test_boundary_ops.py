"""Boundary ops against independent references (numpy / scipy)."""
import numpy as np
import pytest
import torch
from scipy import ndimage
from scipy.spatial.distance import directed_hausdorff

from cbnet_mmdet.models.losses.boundary_ops import (dice_coefficient,
                                                    distance_weighted_error,
                                                    hausdorff_distance,
                                                    mask_contour,
                                                    mask_diagonal,
                                                    squared_distance_to_set)


def ref_contour(mask, k=3):
    eroded = ndimage.binary_erosion(mask, np.ones((k, k)), border_value=0)
    return mask & ~eroded


def ref_hausdorff(a, b):
    """Normalised symmetric HD of contours via scipy (empty: 0 / 1)."""
    pa, pb = np.argwhere(ref_contour(a)), np.argwhere(ref_contour(b))
    if len(pa) == 0 and len(pb) == 0:
        return 0.
    if len(pa) == 0 or len(pb) == 0:
        return 1.
    hd = max(directed_hausdorff(pa, pb)[0], directed_hausdorff(pb, pa)[0])
    return hd / np.hypot(a.shape[0] - 1, a.shape[1] - 1)


def ref_dice(p, g, squared=True):
    inter = (p * g).sum()
    denom = (p**2 + g**2).sum() if squared else (p + g).sum()
    return 1. if denom == 0 else 2 * inter / denom


def hand_made():
    """Pairs of 16x12 masks with known contours (incl. empty and full)."""
    empty = np.zeros((16, 12), bool)
    full = np.ones((16, 12), bool)
    box = empty.copy()
    box[3:9, 2:7] = True
    shifted = np.roll(box, (5, 4), axis=(0, 1))
    dot = empty.copy()
    dot[15, 11] = True
    ring = full.copy()
    ring[4:12, 3:9] = False
    return np.stack([empty, full, box, box, empty, dot, ring, box]), \
        np.stack([empty, empty, box, shifted, full, full, box, ring])


def random_masks(num, shape, seed):
    rng = np.random.default_rng(seed)
    # blobby masks: thresholded smoothed noise, plus pure noise
    noise = ndimage.gaussian_filter(rng.random((num, ) + shape), (0, 2, 2))
    blobs = noise > np.median(noise, axis=(1, 2), keepdims=True)
    return blobs, rng.random((num, ) + shape) > 0.7


def test_mask_diagonal():
    assert mask_diagonal(28, 28) == pytest.approx(27 * np.sqrt(2))
    assert mask_diagonal(1, 1) == 1.


@pytest.mark.parametrize('k', [3, 5])
def test_mask_contour_matches_scipy(k):
    blobs, noise = random_masks(6, (20, 17), seed=1)
    a, b = hand_made()
    masks = np.concatenate([blobs, noise])
    out = mask_contour(torch.from_numpy(masks), k).numpy()
    ref = np.stack([ref_contour(m, k) for m in masks])
    np.testing.assert_array_equal(out, ref)
    # float input, hand-made shapes: full mask -> frame, empty -> empty
    out = mask_contour(torch.from_numpy(a).float(), 3).numpy()
    np.testing.assert_array_equal(out, np.stack([ref_contour(m) for m in a]))
    assert out[1].sum() == 2 * 16 + 2 * 12 - 4 and not out[0].any()


def test_mask_contour_bad_input():
    with pytest.raises(ValueError, match='N, H, W'):
        mask_contour(torch.zeros(2, 1, 4, 4))
    with pytest.raises(ValueError, match='edge_kernel'):
        mask_contour(torch.zeros(2, 4, 4), kernel_size=4)


def test_distance_transform_matches_scipy():
    _, noise = random_masks(5, (23, 19), seed=2)
    sets = noise.copy()
    sets[0] = False  # empty set: everything at the cap
    sets[1] = False
    sets[1, 22, 0] = True  # single far corner point
    out = squared_distance_to_set(torch.from_numpy(sets)).numpy()
    cap = mask_diagonal(23, 19)
    for i in range(1, 5):
        ref = ndimage.distance_transform_edt(~sets[i])**2
        np.testing.assert_allclose(out[i], np.minimum(ref, cap**2),
                                   rtol=1e-6)
    np.testing.assert_allclose(out[0], cap**2, rtol=1e-6)
    assert out[1, 0, 18] == pytest.approx(cap**2)


@pytest.mark.parametrize('stride', [2, 3])
def test_coarse_distance_transform(stride):
    """Coarse grid: scipy EDT on any-pooled blocks, error <= (s-1)sqrt2."""
    blobs, noise = random_masks(4, (28, 25), seed=6)
    sets = np.concatenate([ref_contour(m)[None] for m in blobs] + [noise])
    out = squared_distance_to_set(torch.from_numpy(sets), stride=stride)
    cap = mask_diagonal(28, 25)
    hc, wc = -(-28 // stride), -(-25 // stride)
    for i, s in enumerate(sets):
        padded = np.zeros((hc * stride, wc * stride), bool)
        padded[:28, :25] = s
        coarse = padded.reshape(hc, stride, wc, stride).any((1, 3))
        ref = ndimage.distance_transform_edt(~coarse) * stride
        ref = np.kron(ref, np.ones((stride, stride)))[:28, :25]
        ref = np.minimum(ref, cap)
        np.testing.assert_allclose(out[i].sqrt().numpy(), ref, rtol=1e-5)
        exact = np.minimum(ndimage.distance_transform_edt(~s), cap)
        assert np.abs(ref - exact).max() <= (stride - 1) * np.sqrt(2) + 1e-6
    with pytest.raises(ValueError, match='stride'):
        squared_distance_to_set(torch.from_numpy(sets), stride=0)


def test_hausdorff_matches_scipy():
    blobs, noise = random_masks(20, (28, 28), seed=3)
    a, b = hand_made()
    flipped = np.ascontiguousarray(blobs[::-1])
    for pred, gt in ((blobs, noise), (blobs, flipped), (a, b)):
        out = hausdorff_distance(
            torch.from_numpy(pred).float(), torch.from_numpy(gt).float())
        ref = [ref_hausdorff(p, g) for p, g in zip(pred, gt)]
        np.testing.assert_allclose(out.numpy(), ref, atol=1e-6)
    # hand-made values: identical 0, empty/empty 0, empty vs full 1,
    # shifted box: contour points move by (5, 4)
    out = hausdorff_distance(torch.from_numpy(a), torch.from_numpy(b),
                             normalise=False)
    diag = mask_diagonal(16, 12)
    np.testing.assert_allclose(out[[0, 2]].numpy(), 0., atol=1e-6)
    assert out[1] == pytest.approx(diag) and out[4] == pytest.approx(diag)
    assert out[3] == pytest.approx(np.hypot(5, 4))


def test_dice_matches_numpy():
    rng = np.random.default_rng(4)
    a, b = hand_made()
    probs = rng.random((8, 16, 12))
    for squared in (True, False):
        for p, g in ((a.astype(float), b.astype(float)), (probs, b * 1.)):
            out = dice_coefficient(
                torch.from_numpy(p), torch.from_numpy(g), squared=squared)
            ref = [ref_dice(x, y, squared) for x, y in zip(p, g)]
            np.testing.assert_allclose(out.numpy(), ref, rtol=1e-10)
    out = dice_coefficient(torch.from_numpy(a) * 1., torch.from_numpy(b) * 1.)
    # empty/empty 1, empty/full 0, identical 1
    np.testing.assert_allclose(out[[0, 1, 2, 4]].numpy(), [1, 0, 1, 0])
    with pytest.raises(ValueError, match='same shape'):
        dice_coefficient(torch.zeros(2, 4, 4), torch.zeros(2, 4, 5))


def test_distance_weighted_error_matches_reference():
    """Karimi-style HD_DT term against scipy distance transforms."""
    rng = np.random.default_rng(5)
    blobs, _ = random_masks(6, (28, 28), seed=5)
    a, b = hand_made()
    for gt, probs in ((blobs, rng.random((6, 28, 28))),
                      (b, rng.random((8, 16, 12))), (b, a * 1.)):
        for alpha in (2., 1.):
            out = distance_weighted_error(
                torch.from_numpy(probs).float(), torch.from_numpy(gt) * 1.,
                alpha=alpha)
            diag = mask_diagonal(*gt.shape[1:])
            ref = []
            for p, g in zip(probs, gt):
                dist = []
                for m in (g, p >= 0.5):
                    c = ref_contour(m)
                    d = ndimage.distance_transform_edt(~c) if c.any() else \
                        np.full(m.shape, diag)
                    dist.append(np.minimum(d, diag) / diag)
                ref.append(((p - g)**2 * (dist[0]**alpha + dist[1]**alpha)
                            ).mean() / 2)
            np.testing.assert_allclose(out.numpy(), ref, rtol=1e-4,
                                       atol=1e-7)
    # bounded: worst case (all wrong, empty vs full) stays <= 1
    worst = distance_weighted_error(torch.ones(1, 8, 8), torch.zeros(1, 8, 8))
    assert 0 < worst.item() <= 1
    perfect = distance_weighted_error(torch.from_numpy(b) * 1.,
                                      torch.from_numpy(b) * 1.)
    assert torch.all(perfect == 0)


@pytest.mark.parametrize('stride', [1, 2, 3])
def test_distance_weighted_error_gradient_matches_autograd(stride):
    """The hand-fused forward / backward (row-wise weights, in-place
    buffers) against plain autograd on the upsampled distance maps."""
    rng = np.random.default_rng(7)
    blobs, _ = random_masks(5, (28, 25), seed=7)  # 25: stride 2, 3 pad
    gt = torch.from_numpy(blobs).double()
    probs = torch.from_numpy(rng.random((5, 28, 25))).requires_grad_()
    out = distance_weighted_error(probs, gt, dist_stride=stride)
    grad_out = torch.arange(1., 6., dtype=torch.float64)
    grad, = torch.autograd.grad(out, probs, grad_out)
    diag_sq = mask_diagonal(28, 25)**2
    weight = sum(
        squared_distance_to_set(mask_contour(m), stride=stride) / diag_sq
        for m in (gt, probs.detach() >= 0.5)).double()
    ref_probs = probs.detach().clone().requires_grad_()
    ref = ((ref_probs - gt)**2 * weight).mean((1, 2)) / 2
    ref_grad, = torch.autograd.grad(ref, ref_probs, grad_out)
    torch.testing.assert_close(out, ref, rtol=1e-6, atol=1e-9)
    torch.testing.assert_close(grad, ref_grad, rtol=1e-6, atol=1e-9)
    assert not out.requires_grad or out.grad_fn is not None
