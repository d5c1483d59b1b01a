import filecmp
import glob
import json
import os.path as osp

import numpy as np
import pytest
from cityscapesscripts.helpers.annotation import Annotation
from cityscapesscripts.helpers.labels import id2label, name2label
from cityscapesscripts.preparation.json2labelImg import createLabelImage
from PIL import Image
from scipy import ndimage

from cbnet_mmdet.datasets.cityscapes_paths import FOGGY_BETAS, foggy_path
from cbnet_tools.synthetic import (INSTANCE_CLASSES, add_fog,
                                   generate_cityscapes_like, load_record)
from cbnet_tools.synthetic.cityscapes_like import (ATMOSPHERIC_LIGHT,
                                                   DEPTH_SCALE)
from cbnet_tools.synthetic.scene import (CAMERA_HEIGHT, FOCAL_PER_WIDTH,
                                         HORIZON, SKY_DEPTH)

EVAL_IDS = [name2label[c].id for c in INSTANCE_CLASSES]


def _png(path):
    return np.asarray(Image.open(path))


def _records(root):
    rec = load_record(root)
    return [r for split in ('train', 'val') for r in rec['splits'][split]]


def _gt(root, r, kind):
    return osp.join(root, 'gtFine', r['split'], r['city'],
                    f"{r['stem']}_gtFine_{kind}")


def _img(root, r):
    return osp.join(root, 'leftImg8bit', r['split'], r['city'],
                    f"{r['stem']}_leftImg8bit.png")


def _depth(root, r):
    """The stored depth, metres."""
    return _png(osp.join(root, 'depth', r['split'], r['city'],
                         r['stem'] + '_depth.png')) / DEPTH_SCALE


def _instance_masks(root, r):
    """``(label name, bool mask)`` of each non-crowd instance."""
    inst = _png(_gt(root, r, 'instanceIds.png')).astype(np.int64)
    return [(id2label[int(i) // 1000].name, inst == i)
            for i in np.unique(inst[inst >= 1000])]


def test_layout_and_encodings(cityscapes_like_root):
    root = cityscapes_like_root
    records = _records(root)
    assert len(records) == 7
    for r in records:
        img = _png(_img(root, r))
        assert img.shape == (128, 256, 3) and img.dtype == np.uint8
        label = _png(_gt(root, r, 'labelIds.png'))
        inst = _png(_gt(root, r, 'instanceIds.png'))
        assert label.dtype == np.uint8 and inst.shape == label.shape
        # Cityscapes encoding: instance ids k*1000+i carry their label id,
        # everything else (stuff, crowd) is the label id itself
        expect = np.where(inst >= 1000, inst // 1000, inst)
        np.testing.assert_array_equal(expect, label)
        # the polygons JSON rasterised by cityscapesscripts gives labelIds
        ann = Annotation()
        ann.fromJsonFile(_gt(root, r, 'polygons.json'))
        assert (ann.imgHeight, ann.imgWidth) == (128, 256)
        np.testing.assert_array_equal(
            np.asarray(createLabelImage(ann, 'ids')), label)
        depth = _png(osp.join(root, 'depth', r['split'], r['city'],
                              r['stem'] + '_depth.png'))
        assert depth.dtype == np.uint16
        assert depth.max() == round(SKY_DEPTH * DEPTH_SCALE)  # sky
        for beta in FOGGY_BETAS:
            assert osp.isfile(foggy_path(_img(root, r), beta))


def test_instances_as_specified(cityscapes_like_root):
    records = _records(cityscapes_like_root)
    by_stem = {r['stem']: r for r in records}
    # image 2 of each split is empty, image 0 has a crowd region
    for stem in ('aachen_000002_000019', 'frankfurt_000002_000019'):
        assert by_stem[stem]['instances'] == []
        inst = _png(_gt(cityscapes_like_root, by_stem[stem],
                        'instanceIds.png'))
        assert not np.isin(np.where(inst >= 1000, inst // 1000, inst),
                           EVAL_IDS).any()
    for stem in ('aachen_000000_000019', 'frankfurt_000000_000019'):
        assert any(i['iscrowd'] for i in by_stem[stem]['instances'])
    areas = []
    for r in records:
        if r['instances']:
            # every non-empty image shows all 8 classes (non-crowd)
            assert {i['label'] for i in r['instances']
                    if not i['iscrowd']} == set(INSTANCE_CLASSES)
        areas += [i['area'] for i in r['instances']]
    # many scales: from a few pixels to a sizeable part of the image
    assert min(areas) < 16 and max(areas) > 1000


def test_occlusion_present(cityscapes_like_root):
    """Objects hide each other: each instance's mask is the visible part of
    its polygon (drawn alone by cityscapesscripts), and many are partly
    hidden, some mostly."""
    root = cityscapes_like_root
    shares = []
    for r in _records(root):
        ann = Annotation()
        ann.fromJsonFile(_gt(root, r, 'polygons.json'))
        inst = _png(_gt(root, r, 'instanceIds.png'))
        counts = {}
        for obj in ann.objects:
            if obj.label not in INSTANCE_CLASSES:
                continue
            k = counts.get(obj.label, 0)
            counts[obj.label] = k + 1
            alone = Annotation()
            alone.imgWidth, alone.imgHeight = ann.imgWidth, ann.imgHeight
            alone.objects = [obj]
            full = np.asarray(createLabelImage(alone, 'ids')) > 0
            visible = inst == name2label[obj.label].id * 1000 + k
            assert not (visible & ~full).any()
            if visible.any():
                shares.append(visible.sum() / full.sum())
    shares = np.array(shares)
    assert len(shares) >= 50
    assert (shares < 0.99).mean() > 0.3  # partly hidden
    assert (shares < 0.5).sum() >= 5  # mostly hidden


def test_small_objects_and_perspective(cityscapes_like_root):
    """Many small instances; and perspective: a person standing on the
    road at depth Z has its foot ``f h / Z`` below the horizon and is
    ``f 1.75 / Z`` tall, so its height over its foot's distance below the
    horizon is 1.75 m / camera height, whatever its size."""
    root = cityscapes_like_root
    rel, ratios = [], []
    for r in _records(root):
        for _, m in _instance_masks(root, r):
            rel.append(np.sqrt(m.sum() / m.size))
        ann = Annotation()
        ann.fromJsonFile(_gt(root, r, 'polygons.json'))
        horizon = HORIZON * ann.imgHeight
        for obj in ann.objects:
            ys = np.array([p.y for p in obj.polygon])
            if obj.label == 'person' and 0 < ys.min() and \
                    ys.max() < ann.imgHeight - 1 and ys.max() - ys.min() > 8:
                ratios.append((ys.max() - ys.min()) / (ys.max() - horizon))
    rel = np.array(rel)
    # sqrt(area / image area) < 0.05: under 51 px squared at 1024x2048
    assert (rel < 0.05).mean() > 0.25, np.histogram(rel, 10)
    assert (rel > 0.15).sum() >= 3  # and some large ones
    assert len(ratios) >= 5
    # integer vertices: a pixel of slack on small persons
    np.testing.assert_allclose(np.median(ratios), 1.75 / CAMERA_HEIGHT,
                               rtol=0.08)
    assert np.percentile(np.abs(np.array(ratios) - 1.75 / CAMERA_HEIGHT),
                         75) < 0.25


def test_thin_parts(cityscapes_like_root):
    """Riders, persons and two-wheelers have thin parts (limbs, tyres,
    handlebars): a 3x3 erosion removes most of their pixels."""
    root = cityscapes_like_root
    thin = set()
    for r in _records(root):
        for name, m in _instance_masks(root, r):
            if name in ('person', 'rider', 'bicycle', 'motorcycle') and \
                    m.sum() >= 20:
                kept = ndimage.binary_erosion(m, np.ones((3, 3))).sum()
                if kept < 0.4 * m.sum():
                    thin.add(name)
    assert {'rider', 'bicycle'} <= thin, thin


def test_see_through_bicycles(cityscapes_like_root):
    """A bicycle's mask has no holes (Cityscapes' policy) but its wheels and
    frame show what is behind: deeper pixels inside the mask."""
    root = cityscapes_like_root
    see = 0
    for r in _records(root):
        depth = _depth(root, r)
        for name, m in _instance_masks(root, r):
            d = depth[m]
            if name == 'bicycle' and (d > np.median(d) + 2.0).mean() > 0.1:
                see += 1
            if name == 'bicycle':  # no hole: the mask is its filled self
                filled = ndimage.binary_fill_holes(m)
                assert (filled & ~m).sum() <= 0.02 * m.sum() + 2
    assert see >= 2


def test_depth_follows_the_scene(cityscapes_like_root):
    """The stored depth is the scene's: the road follows the ground plane
    of the camera (re-derived here from its constants), the sky is at
    SKY_DEPTH."""
    root = cityscapes_like_root
    for r in _records(root):
        depth = _depth(root, r)
        label = _png(_gt(root, r, 'labelIds.png'))
        h, w = label.shape
        rows = np.arange(h)[:, None] + 0.5 - HORIZON * h
        with np.errstate(divide='ignore'):
            ground = FOCAL_PER_WIDTH * w * CAMERA_HEIGHT / rows
        ground = np.broadcast_to(np.minimum(np.where(
            rows > 0, ground, SKY_DEPTH), SKY_DEPTH), (h, w))
        road = label == name2label['road'].id
        assert road.sum() > 0.1 * h * w
        np.testing.assert_allclose(depth[road], ground[road],
                                   atol=0.5 / DEPTH_SCALE)
        sky = label == name2label['sky'].id
        assert sky.any() and (depth[sky] == SKY_DEPTH).all()


@pytest.mark.parametrize('label_name, least', [
    ('road', 1.5), ('vegetation', 1.5), ('building', 4.0)])
def test_textured(cityscapes_like_root, label_name, least):
    """Road, trees and buildings are textured, not flat colour plus pixel
    noise: the means of their 4x4 pixel blocks still vary (median absolute
    deviation, which lane marks and shadows barely move; a flat colour
    with the sensor noise gives about 0.3)."""
    root = cityscapes_like_root
    spread = []
    for r in _records(root):
        img = _png(_img(root, r)).astype(float).mean(-1)
        sel = _png(_gt(root, r, 'labelIds.png')) == name2label[label_name].id
        h, w = (s // 4 * 4 for s in img.shape)
        blocks = img[:h, :w].reshape(h // 4, 4, w // 4, 4).mean((1, 3))
        blocks = blocks[sel[:h, :w].reshape(h // 4, 4, w // 4, 4).all(
            (1, 3))]
        if len(blocks) >= 10:
            spread.append(np.median(np.abs(blocks - np.median(blocks))))
    assert len(spread) >= 3 and np.median(spread) > least, spread


def test_fog_model(cityscapes_like_root):
    root = cityscapes_like_root
    r = _records(root)[0]
    clear = _png(_img(root, r))
    depth = _png(osp.join(root, 'depth', r['split'], r['city'],
                          r['stem'] + '_depth.png')) / DEPTH_SCALE
    light = np.asarray(ATMOSPHERIC_LIGHT)
    prev = None
    for beta in FOGGY_BETAS:
        foggy = _png(foggy_path(_img(root, r), beta)).astype(float)
        t = np.exp(-beta * depth)[..., None]
        ref = (clear / 255.0 * t + light * (1 - t)) * 255
        assert np.abs(foggy - ref).max() <= 0.5 + 1e-6
        # the sky (600 m) is washed out at beta 0.02
        if beta == 0.02:
            sky = depth == SKY_DEPTH
            np.testing.assert_allclose(foggy[sky].mean(0), light * 255,
                                       atol=1)
        # denser fog: further from the clear image
        dist = np.abs(foggy - clear).mean()
        if prev is not None:
            assert dist > prev
        prev = dist


def test_add_fog_limits():
    rgb = np.full((2, 2, 3), 200, np.uint8)
    np.testing.assert_array_equal(add_fog(rgb, np.zeros((2, 2)), 0.02), rgb)
    far = add_fog(rgb, np.full((2, 2), 1e4), 0.02, light=(1, 1, 1))
    assert (far == 255).all()


def test_deterministic(tmp_path):
    kw = dict(num_train=1, num_val=1, img_size=(96, 192), betas=(0.02, ))
    generate_cityscapes_like(str(tmp_path / 'a'), seed=3, **kw)
    generate_cityscapes_like(str(tmp_path / 'b'), seed=3, nproc=2, **kw)
    generate_cityscapes_like(str(tmp_path / 'c'), seed=4, **kw)
    files = sorted(
        osp.relpath(p, tmp_path / 'a')
        for p in glob.glob(str(tmp_path / 'a' / '**' / '*.*'),
                           recursive=True))
    assert len(files) == 2 * 6 + 1
    match, mismatch, errors = filecmp.cmpfiles(
        tmp_path / 'a', tmp_path / 'b', files, shallow=False)
    assert mismatch == [] and errors == []
    _, mismatch, _ = filecmp.cmpfiles(
        tmp_path / 'a', tmp_path / 'c', files, shallow=False)
    assert any(f.endswith('_leftImg8bit.png') for f in mismatch)
    with open(tmp_path / 'a' / 'generator_record.json') as f:
        assert json.load(f)['seed'] == 3


def test_bad_arguments(tmp_path):
    with pytest.raises(ValueError, match='0.03'):
        generate_cityscapes_like(str(tmp_path), 1, 1, betas=(0.03, ))
    with pytest.raises(ValueError, match='32x32'):
        generate_cityscapes_like(str(tmp_path), 1, 1, img_size=(16, 64))
    with pytest.raises(ValueError, match='density'):
        generate_cityscapes_like(str(tmp_path), 1, 1, density=0)
