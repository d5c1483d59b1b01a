"""CBNetAddFog: fog on a photograph without depth, from the
atmospheric scattering model and a ground-plane row prior.

References are computed here from the formula, pixel by pixel in float64
(``I = J t + 255 A (1 - t)``, ``t = exp(-beta d)``, ``d = h f / (v - v_h)``
below the horizon, ``c f / (v_h - v)`` above it), not with the
transform's own helpers.
"""
import math

import numpy as np
import pytest
from mmcv import imwrite
from mmcv.transforms import Compose
from mmdet.registry import TRANSFORMS
from mmengine.registry import init_default_scope

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.datasets.transforms import CBNetAddFog

init_default_scope('mmdet')  # MMDet's transforms in mmcv's Compose

#: A camera unlike the defaults, so the test sees every knob used.
CAMERA = dict(
    camera_height=1.5,
    focal_length=1.0,
    horizon=0.25,
    ceiling_height=3.0,
    max_distance=50.0)


def photo(h=24, w=32, seed=0):
    """A random ``uint8[h, w, 3]`` BGR image."""
    return np.random.RandomState(seed).randint(0, 256, (h, w, 3), np.uint8)


def reference_distance(h, w, camera_height, focal_length, horizon,
                       ceiling_height, max_distance):
    """``d`` of each row, metres: the ground plane (below the horizon) and
    the ceiling plane (above it) seen by a level camera."""
    out = []
    for i in range(h):
        v = i + 0.5  # row centre, pixels from the top
        below = v - horizon * h
        if below > 0:
            d = camera_height * focal_length * w / below
        elif below < 0 and ceiling_height is not None:
            d = ceiling_height * focal_length * w / -below
        else:
            d = max_distance
        out.append(min(d, max_distance))
    return out


def reference_fog(img, beta, light_rgb, camera):
    """``I`` in float64 (not rounded), BGR image, RGB light in [0, 1]."""
    h, w = img.shape[:2]
    dist = reference_distance(h, w, **camera)
    out = np.empty(img.shape, np.float64)
    for i in range(h):
        t = math.exp(-beta * dist[i])
        for j in range(w):
            for c in range(3):
                a = 255.0 * light_rgb[2 - c]  # BGR image
                out[i, j, c] = float(img[i, j, c]) * t + a * (1 - t)
    return out


def build(**kwargs):
    return TRANSFORMS.build(dict(type='CBNetAddFog', **kwargs))


@pytest.mark.parametrize('dtype', [np.uint8, np.float32, np.float64])
def test_beta_zero_is_identity(dtype):
    img = photo().astype(dtype)
    out = build(beta=0.0)(dict(img=img.copy()))
    assert out['img'].dtype == dtype and out['img'].shape == img.shape
    np.testing.assert_array_equal(out['img'], img)
    assert out['fog_beta'] == 0.0 and out['fog_light'] is None
    # the formula itself, not only the skip: t = 1 everywhere
    foggy, _ = build().fog(img, 0.0)
    assert foggy.dtype == dtype
    np.testing.assert_array_equal(foggy, img)


@pytest.mark.parametrize('ceiling', [3.0, None])
def test_transmission_against_reference(ceiling):
    h, w, beta = 8, 10, 0.07
    camera = dict(CAMERA, ceiling_height=ceiling)
    fog = build(beta=beta, **camera)
    dist = reference_distance(h, w, **camera)
    # rows 0-1 are above the horizon (v_h = 2 px): the ceiling 3 m above
    # the camera at 3 * 10 / 1.5 = 20 m (row 0) and 3 * 10 / 0.5 = 60 m,
    # beyond the 50 m clamp (row 1); without a ceiling both at the clamp;
    # rows below: the road
    assert dist[:2] == ([20.0, 50.0] if ceiling else [50.0, 50.0])
    assert dist[7] == pytest.approx(1.5 * 10 / 5.5)
    np.testing.assert_allclose(fog.distance(h, w), dist, rtol=1e-12)
    np.testing.assert_allclose(
        fog.transmission(h, w, beta), [math.exp(-beta * d) for d in dist],
        rtol=1e-12)


def test_horizon_row_is_farthest():
    # 9 rows, horizon at 4.5 px: the centre of row 4
    dist = build(horizon=0.5).distance(9, 16)
    assert dist[4] == 600.0
    assert (np.diff(dist[:5]) > 0).all() and (np.diff(dist[4:]) < 0).all()


@pytest.mark.parametrize('light', [(0.82, 0.83, 0.85), (1.0, 0.6, 0.2)])
def test_image_against_reference(light):
    h, w, beta = 8, 10, 0.07
    img = photo(h, w, seed=1)
    ref = reference_fog(img, beta, light, CAMERA)
    out = build(
        beta=beta, atmospheric_light=light, **CAMERA)(
            dict(img=img.copy()))
    assert out['img'].dtype == np.uint8 and out['img'].shape == img.shape
    # float32 arithmetic, then rounding: at most one grey level off, and
    # only where the float64 value sits on a rounding tie
    diff = np.abs(out['img'].astype(np.float64) - np.rint(ref))
    assert diff.max() <= 1
    assert (diff == 0).mean() > 0.98
    assert out['fog_beta'] == beta
    np.testing.assert_allclose(out['fog_light'], light[::-1])
    # float images are not rounded
    out = build(
        beta=beta, atmospheric_light=light, **CAMERA)(
            dict(img=img.astype(np.float64)))
    assert out['img'].dtype == np.float64
    np.testing.assert_allclose(out['img'], ref, rtol=1e-12, atol=1e-9)


def test_channel_order():
    img = np.zeros((6, 4, 3), np.uint8)
    # no ceiling: every row at or above the horizon (here all) at 600 m;
    # beta 1/m gives t = exp(-600), pure light
    for order, pixel in (('bgr', [51, 153, 255]), ('rgb', [255, 153, 51])):
        out = build(
            beta=1.0,
            atmospheric_light=(1.0, 0.6, 0.2),
            channel_order=order,
            horizon=1.0,
            ceiling_height=None)(
                dict(img=img.copy()))
        np.testing.assert_array_equal(out['img'],
                                      np.broadcast_to(pixel, img.shape))


@pytest.mark.parametrize('dtype', [np.uint8, np.float64])
def test_monotone_in_beta(dtype):
    img = photo(48, 64, seed=2).astype(dtype)
    fog = build(**CAMERA)
    betas = [0.0, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.3]
    light = 255.0 * np.asarray(CBNetAddFog().light(img))
    dists, stds = [], []
    for beta in betas:
        foggy, _ = fog.fog(img, beta)
        dists.append(np.abs(foggy.astype(np.float64) - light))
        stds.append(foggy.astype(np.float64).std(axis=(0, 1)).mean())
    for prev, nxt in zip(dists, dists[1:]):
        # per pixel: never farther from A (rounding is monotone too)
        assert (nxt <= prev + 1e-9).all()
        assert nxt.mean() < prev.mean()
    assert all(b < a for a, b in zip(stds, stds[1:]))  # contrast falls
    # beta 0.3 over >= 3.5 m: almost all the contrast is gone
    assert stds[-1] < 0.5 * stds[0]


def test_dark_channel_light():
    rng = np.random.RandomState(3)
    img = rng.randint(0, 60, (60, 80, 3)).astype(np.uint8)
    # a bright haze-like patch wider than the 15 px window: the largest
    # dark channel values are inside it
    img[10:30, 40:65] = (200, 210, 220)
    # brighter, but small: their 15 px windows hold dark pixels
    img[50, 5] = (255, 255, 255)
    img[45:50, 10:20] = (250, 250, 250)
    fog = build(beta=0.02, atmospheric_light='dark_channel')
    expected = np.array([200, 210, 220]) / 255.0
    np.testing.assert_allclose(fog.light(img), expected)
    out = fog(dict(img=img.copy()))
    np.testing.assert_allclose(out['fog_light'], expected)
    # channel_order does not reorder an estimate made on the image itself
    rgb = build(atmospheric_light='dark_channel', channel_order='rgb')
    np.testing.assert_allclose(rgb.light(img), fog.light(img))


def test_prob_and_seed_reproducible():
    fog = build(beta=(0.005, 0.05), prob=0.5)
    img = photo()

    def run(seed):
        np.random.seed(seed)
        outs = [fog(dict(img=img.copy())) for _ in range(40)]
        return [o['fog_beta'] for o in outs], [o['img'] for o in outs]

    betas, imgs = run(7)
    again, imgs_again = run(7)
    assert betas == again
    for a, b in zip(imgs, imgs_again):
        np.testing.assert_array_equal(a, b)
    assert run(8)[0] != betas
    applied = [b for b in betas if b > 0]
    assert 5 < len(applied) < 35  # prob 0.5 of 40
    assert all(0.005 <= b <= 0.05 for b in applied)
    assert len(set(applied)) == len(applied)  # drawn per image
    for beta, out in zip(betas, imgs):
        if beta == 0:
            np.testing.assert_array_equal(out, img)
        else:
            assert not np.array_equal(out, img)
    never = build(beta=0.02, prob=0.0)(dict(img=img.copy()))
    np.testing.assert_array_equal(never['img'], img)
    assert never['fog_beta'] == 0.0


@pytest.mark.parametrize('kwargs, error, match', [
    (dict(beta=-0.01), ValueError, 'beta must be a finite number >= 0'),
    (dict(beta=float('nan')), ValueError, 'finite'),
    (dict(beta=(0.02, 0.01)), ValueError, r'reversed.*\(0.01, 0.02\)'),
    (dict(beta=(-0.01, 0.01)), ValueError, 'bounds >= 0'),
    (dict(beta=(0.01, )), TypeError, r'\(low, high\)'),
    (dict(beta='0.01'), TypeError, 'number'),
    (dict(beta=True), TypeError, 'number'),
    (dict(prob=1.5), ValueError, r'prob must be in \[0, 1\]'),
    (dict(prob=-0.1), ValueError, r'prob must be in \[0, 1\]'),
    (dict(atmospheric_light=1.2), ValueError, 'atmospheric_light'),
    (dict(atmospheric_light=(0.8, 0.8)), ValueError, 'atmospheric_light'),
    (dict(atmospheric_light='sky'), ValueError, 'dark_channel'),
    (dict(channel_order='BGR'), ValueError, 'channel_order'),
    (dict(camera_height=0), ValueError, 'camera_height'),
    (dict(focal_length=-1.0), ValueError, 'focal_length'),
    (dict(max_distance=float('inf')), ValueError, 'max_distance'),
    (dict(horizon=float('nan')), ValueError, 'horizon'),
    (dict(ceiling_height=0.0), ValueError, 'ceiling_height'),
])
def test_bad_arguments(kwargs, error, match):
    with pytest.raises(error, match=match):
        build(**kwargs)


@pytest.mark.parametrize('img, error, match', [
    (np.zeros((8, 8), np.uint8), ValueError, "color_type='color'"),
    (np.zeros((8, 8, 1), np.uint8), ValueError, r'\(8, 8, 1\)'),
    (np.zeros((8, 8, 4), np.uint8), ValueError, 'H x W x 3'),
    (np.zeros((8, 8, 6), np.uint8), ValueError, 'CBNetAddFoggyTwin'),
    (np.zeros((8, 8, 3), np.int16), TypeError, 'int16'),
    (np.zeros((8, 8, 3), np.uint16), TypeError, 'uint8 or float32'),
    (None, TypeError, 'numpy image'),
])
def test_bad_images(img, error, match):
    with pytest.raises(error, match=match):
        build()(dict(img=img, img_path='street.jpg'))


@pytest.mark.parametrize('shape', [(0, 8, 3), (8, 0, 3)])
def test_empty_images(shape):
    """A fixed light fogs nothing and keeps the shape; the dark channel
    light has no pixel to search and says so."""
    out = build(beta=0.02)(dict(img=np.zeros(shape, np.uint8)))
    assert out['img'].shape == shape and out['img'].dtype == np.uint8
    with pytest.raises(ValueError, match='empty'):
        build(beta=0.02, atmospheric_light='dark_channel')(
            dict(img=np.zeros(shape, np.uint8)))


def test_repr_names_every_knob():
    text = repr(build(beta=(0.005, 0.02), prob=0.5, **CAMERA))
    for word in ('beta=(0.005, 0.02)', 'prob=0.5', 'camera_height=1.5',
                 'focal_length=1.0', 'horizon=0.25', 'ceiling_height=3.0',
                 'max_distance=50.0', 'atmospheric_light', 'channel_order'):
        assert word in text


def _data_info(tmp_path, h=48, w=64):
    """A PNG and its data info, as CocoDataset gives it: two instances
    with boxes and polygon masks."""
    path = str(tmp_path / 'street.png')
    imwrite(photo(h, w, seed=4), path)
    return dict(
        img_path=path,
        img_id=0,
        height=h,
        width=w,
        instances=[
            dict(
                bbox=[4.0, 20.0, 30.0, 44.0],
                bbox_label=0,
                ignore_flag=0,
                mask=[[4, 20, 30, 20, 30, 44, 4, 44]]),
            dict(
                bbox=[35.0, 10.0, 60.0, 30.0],
                bbox_label=1,
                ignore_flag=0,
                mask=[[35, 10, 60, 10, 47, 30]]),
        ])


def _pipeline(fog):
    return Compose([
        dict(type='LoadImageFromFile'),
        dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
        *([fog] if fog else []),
        dict(type='Resize', scale=(96, 72), keep_ratio=True),
        dict(type='RandomFlip', prob=0.5),
        dict(
            type='PackDetInputs',
            meta_keys=('img_path', 'img_shape', 'scale_factor', 'flip',
                       'fog_beta')),
    ])


@pytest.mark.parametrize('seed', range(4))
def test_in_mmdet_pipeline_boxes_masks_unchanged(tmp_path, seed):
    info = _data_info(tmp_path)
    outs = {}
    # beta 0 draws from the RNG as beta 0.05 does: the same flips
    for beta in (0.0, 0.05):
        np.random.seed(seed)
        outs[beta] = _pipeline(dict(type='CBNetAddFog', beta=beta))(dict(info))
    clear, foggy = outs[0.0], outs[0.05]
    assert foggy['data_samples'].fog_beta == 0.05
    assert foggy['data_samples'].flip == clear['data_samples'].flip
    assert foggy['inputs'].shape == clear['inputs'].shape == (3, 72, 96)
    assert foggy['inputs'].dtype == clear['inputs'].dtype
    assert not foggy['inputs'].equal(clear['inputs'])
    gt_f = foggy['data_samples'].gt_instances
    gt_c = clear['data_samples'].gt_instances
    assert gt_f.bboxes.tensor.equal(gt_c.bboxes.tensor)
    assert gt_f.labels.equal(gt_c.labels)
    np.testing.assert_array_equal(gt_f.masks.to_ndarray(),
                                  gt_c.masks.to_ndarray())
    assert gt_f.masks.to_ndarray().any()


def test_in_mmdet_pipeline_same_as_without_fog(tmp_path):
    """No RNG in play (flip prob 1): the fog transform changes only the
    image; boxes equal those of the pipeline without it, and the box of
    the first instance is where resize + flip put it."""
    info = _data_info(tmp_path)
    with_fog = _pipeline(dict(type='CBNetAddFog', beta=0.02))
    without = _pipeline(None)
    for p in (with_fog, without):
        p.transforms[-2].prob = 1.0
    a, b = with_fog(dict(info)), without(dict(info))
    boxes = a['data_samples'].gt_instances.bboxes.tensor
    assert boxes.equal(b['data_samples'].gt_instances.bboxes.tensor)
    # x 1.5 (64x48 -> 96x72), then flipped in a 96 px wide image
    np.testing.assert_allclose(boxes[0].numpy(),
                               [96 - 45.0, 30.0, 96 - 6.0, 66.0])
    np.testing.assert_array_equal(
        a['data_samples'].gt_instances.masks.to_ndarray(),
        b['data_samples'].gt_instances.masks.to_ndarray())
