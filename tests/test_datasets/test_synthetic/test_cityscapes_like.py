import filecmp
import glob
import json
import os.path as osp

import numpy as np
import pytest
from cityscapesscripts.helpers.annotation import Annotation
from cityscapesscripts.helpers.labels import name2label
from cityscapesscripts.preparation.json2labelImg import createLabelImage
from PIL import Image

from cbnet_mmdet.datasets.cityscapes_paths import FOGGY_BETAS, foggy_path
from cbnet_mmdet.datasets.synthetic import (INSTANCE_CLASSES, add_fog,
                                            generate_cityscapes_like,
                                            load_record)
from cbnet_mmdet.datasets.synthetic.cityscapes_like import (
    ATMOSPHERIC_LIGHT, DEPTH_SCALE)
from cbnet_mmdet.datasets.synthetic.scene import SKY_DEPTH

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
    """Some objects are partly hidden: the visible area is smaller than the
    polygon drawn alone."""
    root = cityscapes_like_root
    occluded = 0
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
            occluded += int(visible.sum() < full.sum())
    assert occluded >= 3


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
