import json
import os.path as osp

import numpy as np
import pytest
from cityscapesscripts.helpers.labels import id2label
from PIL import Image

from cbnet_tools.coco_statistics import (coco_statistics, format_statistics,
                                         load_coco)
from cbnet_tools.synthetic import INSTANCE_CLASSES


def _ann(root, split):
    return osp.join(root, 'annotations',
                    f'instancesonly_filtered_gtFine_{split}.json')


def _from_pngs(root, split):
    """Instance areas, classes and per-image counts re-derived from the
    instanceIds PNGs with numpy (not from the JSON)."""
    with open(_ann(root, split)) as f:
        images = json.load(f)['images']
    areas, names, per_image, crowd = [], [], [], 0
    for img in images:
        path = osp.join(root, 'gtFine', split, img['file_name'].replace(
            '_leftImg8bit.png', '_gtFine_instanceIds.png'))
        inst = np.asarray(Image.open(path)).astype(np.int64)
        ids, counts = np.unique(inst, return_counts=True)
        label = np.where(ids >= 1000, ids // 1000, ids)
        evaluated = np.isin(label, [24, 25, 26, 27, 28, 31, 32, 33])
        crowd += int((evaluated & (ids < 1000)).sum())
        keep = evaluated & (ids >= 1000)
        areas += counts[keep].tolist()
        names += [id2label[int(i)].name for i in label[keep]]
        per_image.append(int(keep.sum()))
    return np.array(areas, float), names, np.array(per_image), crowd


@pytest.mark.parametrize('split', ['train', 'val'])
def test_matches_the_pngs(cityscapes_like_root, split):
    stats = coco_statistics(load_coco(_ann(cityscapes_like_root, split)))
    areas, names, per_image, crowd = _from_pngs(cityscapes_like_root, split)
    assert stats['images'] == len(per_image)
    assert stats['instances'] == len(areas) and stats['crowd'] == crowd
    assert stats['images_with_instances'] == (per_image > 0).sum()
    assert stats['per_image']['mean'] == pytest.approx(per_image.mean())
    assert stats['per_image']['median'] == np.median(per_image)
    assert stats['per_image']['max'] == per_image.max()
    assert list(stats['per_class']) == list(INSTANCE_CLASSES)
    assert stats['per_class'] == {c: names.count(c) for c in INSTANCE_CLASSES}
    hist = np.histogram(areas, [0, 32**2, 96**2, np.inf])[0] / len(areas)
    assert list(stats['coco_area'].values()) == pytest.approx(hist)
    edges = np.array([0, 8, 16, 32, 64, 96, 128, 256, np.inf])**2
    hist = np.histogram(areas, edges)[0] / len(areas)
    assert list(stats['area_hist'].values()) == pytest.approx(hist)
    assert list(stats['area_hist'])[0] == '[0^2, 8^2)'
    rel = np.sqrt(areas / (128 * 256))
    hist = np.histogram(rel, [0, .01, .02, .05, .1, .2, np.inf])[0]
    assert list(stats['rel_size_hist'].values()) == pytest.approx(
        hist / len(areas))
    text = format_statistics(stats, split)
    assert f'| car | {names.count("car")} |' in text
    assert f'{len(areas)} instances' in text


def _write(tmp_path, coco):
    path = str(tmp_path / 'ann.json')
    with open(path, 'w') as f:
        json.dump(coco, f)
    return path


IMG = dict(id=1, file_name='a.png', height=10, width=20)
CAT = dict(id=26, name='car')


def test_no_annotations(tmp_path):
    stats = coco_statistics(load_coco(_write(
        tmp_path, dict(images=[IMG], annotations=[], categories=[CAT]))))
    assert stats['instances'] == 0 and stats['per_image']['mean'] == 0
    assert set(stats['coco_area'].values()) == {0.0}
    stats = coco_statistics(dict(images=[], annotations=[], categories=[]))
    assert stats['images'] == 0 and stats['per_image']['max'] == 0


@pytest.mark.parametrize('coco, match', [
    ('not json', 'not valid JSON'),
    (dict(images=[IMG], categories=[CAT]), 'no "annotations"'),
    (dict(images=[IMG], categories=[CAT], annotations=[
        dict(id=7, image_id=2, category_id=26, area=3)]),
     'annotation 7 refers to image 2'),
    (dict(images=[IMG], categories=[CAT], annotations=[
        dict(id=8, image_id=1, category_id=99, area=3)]),
     'annotation 8 has unknown category 99'),
    (dict(images=[IMG], categories=[CAT], annotations=[
        dict(id=9, image_id=1, category_id=26, area=-1)]),
     'annotation 9 has no valid "area"'),
])
def test_malformed(tmp_path, coco, match):
    path = str(tmp_path / 'ann.json')
    with open(path, 'w') as f:
        f.write(coco if isinstance(coco, str) else json.dumps(coco))
    with pytest.raises(ValueError, match=match) as err:
        load_coco(path)
    assert path in str(err.value)
    with pytest.raises(FileNotFoundError, match='nowhere'):
        load_coco(str(tmp_path / 'nowhere.json'))
