import importlib.util
import json
import os
import os.path as osp
import re
import shutil

import mmdet  # noqa: F401
import numpy as np
import pycocotools.mask as mask_utils
import pytest
import torch
from mmdet.registry import METRICS
from PIL import Image
from pycocotools.coco import COCO
from pycocotools.cocoeval import COCOeval

from cbnet_tools.cityscapes_to_coco import (collect_files, convert,
                                            image_annotations)
from cbnet_tools.synthetic import INSTANCE_CLASSES, image_stem, load_record


def _load_json(root, split):
    path = osp.join(root, 'annotations',
                    f'instancesonly_filtered_gtFine_{split}.json')
    with open(path) as f:
        return json.load(f)


@pytest.mark.parametrize('split', ['train', 'val'])
def test_matches_what_was_drawn(cityscapes_like_root, split):
    coco = _load_json(cityscapes_like_root, split)
    drawn = load_record(cityscapes_like_root)['splits'][split]
    assert len(coco['images']) == len(drawn)
    by_name = {img['file_name']: img for img in coco['images']}
    for rec in drawn:
        img = by_name[f"{rec['city']}/{rec['stem']}_leftImg8bit.png"]
        assert img['segm_file'] == \
            f"{rec['city']}/{rec['stem']}_gtFine_labelIds.png"
        assert (img['height'], img['width']) == (128, 256)
        anns = [a for a in coco['annotations'] if a['image_id'] == img['id']]
        got = sorted((a['category_id'], a['iscrowd'], a['area'])
                     for a in anns)
        want = sorted((i['label_id'], i['iscrowd'], i['area'])
                      for i in rec['instances'])
        assert got == want  # counts, classes, areas, crowd flags
    assert [c['name'] for c in coco['categories']] == list(INSTANCE_CLASSES)
    assert [c['id'] for c in coco['categories']] == [
        24, 25, 26, 27, 28, 31, 32, 33
    ]
    # ids from 1: pycocotools reads a match to id 0 as no match
    ids = [a['id'] for a in coco['annotations']]
    assert ids == list(range(1, len(ids) + 1))
    assert [img['id'] for img in coco['images']] == list(
        range(1, len(coco['images']) + 1))


def test_masks_and_boxes_exact(cityscapes_like_root):
    root = cityscapes_like_root
    coco = _load_json(root, 'val')
    for img in coco['images']:
        inst = np.asarray(Image.open(
            osp.join(root, 'gtFine', 'val',
                     img['file_name'].replace('leftImg8bit', 'gtFine_'
                                              'instanceIds'))))
        anns = [a for a in coco['annotations'] if a['image_id'] == img['id']]
        cover = np.zeros(inst.shape, int)
        for a in anns:
            m = mask_utils.decode(a['segmentation']).astype(bool)
            cover += m
            ids = np.unique(inst[m])
            assert len(ids) == 1
            assert (ids[0] < 1000) == bool(a['iscrowd'])
            assert (inst == ids[0]).sum() == a['area'] == m.sum()
            ys, xs = np.nonzero(m)
            np.testing.assert_allclose(
                a['bbox'], [xs.min(), ys.min(), xs.ptp() + 1, ys.ptp() + 1])
        assert cover.max() <= 1


def test_same_as_mmdet_converter(cityscapes_like_root):
    """Per image, our annotations equal MMDetection's own converter's."""
    path = osp.join(osp.dirname(mmdet.__file__), '.mim', 'tools',
                    'dataset_converters', 'cityscapes.py')
    spec = importlib.util.spec_from_file_location('_mmdet_cs', path)
    ref = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ref)
    for files in collect_files(cityscapes_like_root, 'val'):
        ours, theirs = image_annotations(files), ref.load_img_info(files)
        key = (lambda a: (a['category_id'], a['segmentation']['counts']))
        assert sorted(ours.pop('anno_info'), key=key) == sorted(
            theirs.pop('anno_info'), key=key)
        assert ours == theirs


def _copy(root, dst):
    shutil.copytree(root, dst, ignore=shutil.ignore_patterns(
        'leftImg8bit_foggy', 'depth', 'annotations'))
    return str(dst)


def test_missing_folder(cityscapes_like_root, tmp_path):
    root = _copy(cityscapes_like_root, tmp_path / 'cs')
    shutil.rmtree(osp.join(root, 'gtFine', 'val'))
    with pytest.raises(FileNotFoundError, match=r'gtFine/val'):
        convert(root, splits=['val'])
    with pytest.raises(FileNotFoundError, match='nowhere'):
        convert(str(tmp_path / 'nowhere'))


def test_image_without_annotation(cityscapes_like_root, tmp_path):
    root = _copy(cityscapes_like_root, tmp_path / 'cs')
    img, inst, _ = collect_files(root, 'val')[1]
    os.remove(inst)
    with pytest.raises(FileNotFoundError) as err:
        convert(root, splits=['val'])
    assert img in str(err.value) and inst in str(err.value)


@pytest.mark.parametrize('which', [0, 1])
def test_corrupt_png(cityscapes_like_root, tmp_path, which):
    root = _copy(cityscapes_like_root, tmp_path / 'cs')
    bad = collect_files(root, 'val')[0][which]
    with open(bad, 'rb') as f:
        data = f.read()
    with open(bad, 'wb') as f:  # truncated for the ids, garbage for the RGB
        f.write(data[:len(data) // 2] if which else b'not a png' * 10)
    with pytest.raises(ValueError, match=re.escape(bad)):
        convert(root, splits=['val'])


def test_empty_split(tmp_path):
    root = tmp_path / 'cs'
    os.makedirs(root / 'leftImg8bit' / 'val' / 'x')
    os.makedirs(root / 'gtFine' / 'val' / 'x')
    with pytest.raises(FileNotFoundError, match='no {city}'):
        convert(str(root), splits=['val'])


def _single_image_tree(root, dst, index):
    """A copy of ``root`` holding only val image ``index`` (image and gtFine
    files), converted."""
    _, stem = image_stem('val', index)
    (files, ) = [f for f in collect_files(root, 'val') if stem in f[0]]
    for path in files:
        rel = osp.relpath(path, root)
        os.makedirs(osp.dirname(dst / rel), exist_ok=True)
        shutil.copy(path, dst / rel)
    return convert(str(dst), splits=['val'])['val']


def test_ground_truth_as_prediction_scores_100(cityscapes_like_root,
                                               tmp_path):
    """Each annotation given back as a detection is a true positive: 100 AP
    through MMDet's CocoMetric and through pycocotools itself. A split
    numbered from 0 loses its first annotation (COCOeval reads a match to
    id 0 as no match) and scores below 100."""
    # val image 1 of the fixture has instances and no crowd region
    ann_file = _single_image_tree(cityscapes_like_root, tmp_path / 'cs', 1)
    with open(ann_file) as f:
        coco = json.load(f)
    anns = coco['annotations']
    (img, ) = coco['images']
    assert anns and not anns[0]['iscrowd'] and len(anns) >= 8
    cat_ids = [c['id'] for c in coco['categories']]

    metric = METRICS.build(dict(type='CocoMetric', ann_file=ann_file,
                                metric=['bbox', 'segm']))
    metric.dataset_meta = dict(
        classes=tuple(c['name'] for c in coco['categories']))
    masks = mask_utils.decode([a['segmentation'] for a in anns])
    boxes = torch.tensor([a['bbox'] for a in anns], dtype=torch.float32)
    boxes[:, 2:] += boxes[:, :2]  # xywh -> xyxy
    metric.process({}, [dict(
        img_id=img['id'], ori_shape=(img['height'], img['width']),
        pred_instances=dict(
            bboxes=boxes, scores=torch.ones(len(anns)),
            labels=torch.tensor(
                [cat_ids.index(a['category_id']) for a in anns]),
            masks=torch.from_numpy(masks.transpose(2, 0, 1).astype(bool))))])
    res = metric.evaluate(1)
    for kind in ('bbox', 'segm'):
        assert res[f'coco/{kind}_mAP'] == 1.0, res
        assert res[f'coco/{kind}_mAP_50'] == 1.0, res

    gt = COCO(ann_file)
    dets = gt.loadRes([dict(image_id=a['image_id'], bbox=a['bbox'],
                            category_id=a['category_id'], score=1.0)
                       for a in anns])
    ev = COCOeval(gt, dets, 'bbox')
    ev.evaluate()
    ev.accumulate()
    ev.summarize()
    assert ev.stats[0] == 1.0  # AP@[.5:.95]
