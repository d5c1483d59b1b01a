import json
import os.path as osp

import numpy as np
import pycocotools.mask as mask_utils
import pytest
import torch
from cityscapesscripts.evaluation import \
    evalPixelLevelSemanticLabeling as cs_eval
from cityscapesscripts.helpers.labels import name2label
from mmdet.registry import METRICS
from mmengine.config import Config
from mmengine.evaluator import Evaluator
from PIL import Image

from cbnet_mmdet.evaluation import CBNetInstanceMIoUMetric
from cbnet_mmdet.evaluation.metrics.instance_miou_metric import (
    confusion_matrix, paint_masks)

CLASSES = ('person', 'rider', 'car', 'truck', 'bus', 'train', 'motorcycle',
           'bicycle')
CAT_IDS = [name2label[c].id for c in CLASSES]
ANN = 'annotations/instancesonly_filtered_gtFine_val.json'
CFG = osp.join(osp.dirname(__file__), '..', '..', '..', 'configs', '_base_',
               'datasets', 'cityscapes_instance.py')


def _coco(root):
    with open(osp.join(root, ANN)) as f:
        return json.load(f)


def _gt_predictions(coco, img, with_crowd=True):
    """Ground truth of one image as model predictions."""
    anns = [a for a in coco['annotations'] if a['image_id'] == img['id']
            and (with_crowd or not a['iscrowd'])]
    h, w = img['height'], img['width']
    masks = (mask_utils.decode([a['segmentation'] for a in anns]).transpose(
        2, 0, 1) if anns else np.zeros((0, h, w), np.uint8))
    boxes = np.array([a['bbox'] for a in anns], np.float32).reshape(-1, 4)
    boxes[:, 2:] += boxes[:, :2]
    return dict(
        bboxes=torch.from_numpy(boxes),
        labels=torch.tensor([CAT_IDS.index(a['category_id']) for a in anns],
                            dtype=torch.long),
        scores=torch.ones(len(anns)),
        masks=torch.from_numpy(masks.astype(bool)))


def _sample(img, pred):
    return dict(img_id=img['id'], ori_shape=(img['height'], img['width']),
                pred_instances=pred)


def _evaluator(root, **miou_kw):
    """Our config's val_evaluator on the generated data."""
    cfg = Config.fromfile(CFG)
    metrics = []
    for m in cfg.val_evaluator:
        if m['type'] == 'CBNetCityScapesMetric':
            continue  # its own test: test_cbnet_cityscapes_metric.py
        m = dict(m, ann_file=osp.join(root, ANN))
        if m['type'] == 'CBNetInstanceMIoUMetric':
            m.update(miou_kw)
        metrics.append(METRICS.build(m))
    ev = Evaluator(metrics)
    ev.dataset_meta = dict(classes=CLASSES)
    return ev


def test_config_evaluators(cityscapes_like_root):
    cfg = Config.fromfile(CFG)
    assert [m['type'] for m in cfg.val_evaluator] == [
        'CocoMetric', 'CBNetInstanceMIoUMetric', 'CBNetCityScapesMetric'
    ]
    assert cfg.test_evaluator == cfg.val_evaluator
    assert cfg.val_dataloader.dataset.type == 'CBNetCityscapesDataset'
    assert cfg.train_dataloader.dataset.dataset.type == \
        'CBNetCityscapesDataset'
    foggy = Config.fromfile(CFG.replace('cityscapes_instance',
                                        'foggy_cityscapes_instance'))
    for ds in (foggy.train_dataloader.dataset.dataset,
               foggy.val_dataloader.dataset, foggy.test_dataloader.dataset):
        assert ds.type == 'CBNetFoggyCityscapesDataset' and ds.beta == 0.02
        assert ds.ann_file.endswith('_val.json') or ds.ann_file.endswith(
            '_train.json')


def test_ground_truth_scores_100(cityscapes_like_root):
    """GT fed back as predictions: bbox and segm AP 1, every class AP
    defined (no -1), mIoU 1 for every class."""
    coco = _coco(cityscapes_like_root)
    ev = _evaluator(cityscapes_like_root)
    ev.process([_sample(img, _gt_predictions(coco, img))
                for img in coco['images']])
    res = ev.evaluate(len(coco['images']))
    for key in ('bbox_mAP', 'bbox_mAP_50', 'bbox_mAP_75', 'segm_mAP',
                'segm_mAP_50', 'segm_mAP_75'):
        assert res[f'coco/{key}'] == 1.0, key
    for c in CLASSES:
        assert res[f'coco/{c}_precision'] == 1.0, c
        assert res[f'cityscapes/IoU_{c}'] == 1.0
    assert res['cityscapes/mIoU'] == 1.0
    # small and medium objects exist in the data and are scored (no large
    # ones at 128x256)
    assert res['coco/segm_mAP_s'] == 1.0 and res['coco/segm_mAP_m'] == 1.0


def _imperfect(coco, img, rng):
    """GT corrupted: shifted masks, dropped and relabelled instances,
    random scores (some below the threshold), extra false positives."""
    pred = _gt_predictions(coco, img, with_crowd=False)
    masks = pred['masks'].numpy()
    labels = pred['labels'].numpy().copy()
    n = len(masks)
    masks = np.stack([
        np.roll(m, tuple(rng.integers(-3, 4, 2)), (0, 1)) for m in masks
    ]) if n else masks
    swap = rng.random(n) < 0.25
    labels[swap] = rng.integers(0, 8, swap.sum())
    keep = rng.random(n) > 0.15
    h, w = masks.shape[1:]
    fp = np.zeros((3, h, w), bool)
    for i in range(3):
        y, x = rng.integers(0, h - 20), rng.integers(0, w - 30)
        fp[i, y:y + 20, x:x + 30] = True
    masks = np.concatenate([masks[keep], fp])
    labels = np.concatenate([labels[keep], rng.integers(0, 8, 3)])
    scores = rng.uniform(0.2, 1.0, len(masks))
    return dict(masks=torch.from_numpy(masks),
                labels=torch.from_numpy(labels),
                scores=torch.from_numpy(scores).float(),
                bboxes=torch.zeros(len(masks), 4))


def _reference_label_map(pred, thr):
    """Naive painter: loop over instances by ascending score."""
    masks, labels, scores = (pred['masks'].numpy(), pred['labels'].numpy(),
                             pred['scores'].numpy())
    out = np.full(masks.shape[1:], name2label['road'].id, np.uint8)
    for i in np.argsort(scores, kind='stable'):
        if scores[i] >= thr:
            out[masks[i]] = CAT_IDS[labels[i]]
    return out


def test_miou_matches_cityscapesscripts(cityscapes_like_root, tmp_path):
    """Imperfect predictions: per-class IoU equals cityscapesscripts'
    pixel-level evaluation of the same predictions painted naively, against
    the released-format labelIds PNGs."""
    root = cityscapes_like_root
    coco = _coco(root)
    rng = np.random.default_rng(0)
    metric = CBNetInstanceMIoUMetric(ann_file=osp.join(root, ANN),
                                     score_thr=0.5)
    metric.dataset_meta = dict(classes=CLASSES)
    args = cs_eval.args
    args.evalInstLevelScore, args.quiet = False, True
    cs_eval.CSUPPORT = False  # its pure NumPy path updates conf in place
    conf = cs_eval.generateMatrix(args)
    for img in coco['images']:
        pred = _imperfect(coco, img, rng)
        metric.process({}, [_sample(img, pred)])
        pred_png = str(tmp_path / f"{img['id']}.png")
        Image.fromarray(_reference_label_map(pred, 0.5)).save(pred_png)
        gt_png = osp.join(root, 'gtFine', 'val', img['segm_file'])
        cs_eval.evaluatePair(pred_png, gt_png, conf, {}, {}, args)
    ours = metric.evaluate(len(coco['images']))
    ref = np.array([cs_eval.getIouScoreForLabel(i, conf, args)
                    for i in CAT_IDS])
    assert 0.2 < np.nanmean(ref) < 0.95  # imperfect but not trivial
    for c, r in zip(CLASSES, ref):
        assert ours[f'cityscapes/IoU_{c}'] == pytest.approx(r, abs=1e-4)
    assert ours['cityscapes/mIoU'] == pytest.approx(np.nanmean(ref),
                                                    abs=1e-4)


def test_paint_order_and_threshold():
    masks = np.zeros((3, 4, 4), bool)
    masks[0, :, :3] = True       # big, label 1, score .9
    masks[1, :2, :2] = True      # small, label 2, score .6
    masks[2, 3, 3] = True        # label 3, below threshold
    pred = dict(masks=torch.from_numpy(masks),
                labels=torch.tensor([0, 1, 2]),
                scores=torch.tensor([0.9, 0.6, 0.3]))
    by_score = CBNetInstanceMIoUMetric(score_thr=0.5).pred_map(pred, (4, 4))
    by_area = CBNetInstanceMIoUMetric(
        score_thr=0.5, paint_order='area').pred_map(pred, (4, 4))
    expect = np.zeros((4, 4), np.uint8)
    expect[:, :3] = 1
    np.testing.assert_array_equal(by_score, expect)
    expect[:2, :2] = 2  # the smaller mask stays on top
    np.testing.assert_array_equal(by_area, expect)
    # RLE input gives the same map
    rles = [mask_utils.encode(np.asfortranarray(m.astype(np.uint8)))
            for m in masks]
    np.testing.assert_array_equal(
        CBNetInstanceMIoUMetric(score_thr=0.5).pred_map(
            dict(pred, masks=rles), (4, 4)), by_score)


def test_paint_masks_ties_and_empty():
    masks = np.ones((2, 2, 2), bool)
    out = paint_masks(masks, np.array([5, 7]), np.array([1.0, 1.0]))
    assert (out == 7).all()  # equal priority: the later one wins
    assert (paint_masks(np.zeros((0, 3, 2), bool), np.zeros(0), np.zeros(0),
                        background=4) == 4).all()


def test_confusion_matrix_against_numpy_loop():
    rng = np.random.default_rng(1)
    gt = rng.integers(0, 4, (30, 40)).astype(np.uint8)
    gt[:3] = 255
    pred = rng.integers(0, 4, (30, 40)).astype(np.uint8)
    cm = confusion_matrix(gt, pred, 4)
    for i in range(4):
        for j in range(4):
            assert cm[i, j] == ((gt == i) & (pred == j)).sum()


def test_empty_and_absent_classes(cityscapes_like_root):
    """No predictions: IoU 0 for classes in the GT; an image without GT and
    predictions contributes nothing (NaN classes are left out of the
    mean)."""
    root = cityscapes_like_root
    coco = _coco(root)
    empty = dict(masks=torch.zeros(0, 128, 256, dtype=torch.bool),
                 labels=torch.zeros(0, dtype=torch.long),
                 scores=torch.zeros(0))
    metric = CBNetInstanceMIoUMetric(ann_file=osp.join(root, ANN))
    metric.dataset_meta = dict(classes=CLASSES)
    metric.process({}, [_sample(img, empty) for img in coco['images']])
    res = metric.evaluate(3)
    assert res['cityscapes/mIoU'] == 0.0
    empty_img = [img for img in coco['images'] if not any(
        a['image_id'] == img['id'] for a in coco['annotations'])]
    assert len(empty_img) == 1
    metric.process({}, [_sample(empty_img[0], empty)])
    res = metric.evaluate(1)
    assert np.isnan(res['cityscapes/mIoU'])
    assert all(np.isnan(res[f'cityscapes/IoU_{c}']) for c in CLASSES)


def test_raw_instances_and_crowd_ignore(cityscapes_like_root):
    """Without ann_file the metric renders the raw 'instances'; with
    ignore_crowd, predictions without the crowd regions still score 1."""
    root = cityscapes_like_root
    coco = _coco(root)
    img = coco['images'][0]
    anns = [a for a in coco['annotations'] if a['image_id'] == img['id']]
    assert any(a['iscrowd'] for a in anns)
    instances = [dict(mask=a['segmentation'],
                      bbox_label=CAT_IDS.index(a['category_id']),
                      ignore_flag=a['iscrowd']) for a in anns]
    no_crowd = _gt_predictions(coco, img, with_crowd=False)
    results = {}
    for ignore in (False, True):
        metric = CBNetInstanceMIoUMetric(ignore_crowd=ignore)
        metric.dataset_meta = dict(classes=CLASSES)
        metric.process({}, [dict(_sample(img, no_crowd),
                                 instances=instances)])
        results[ignore] = metric.evaluate(1)['cityscapes/mIoU']
    assert results[True] == 1.0 and results[False] < 1.0


def test_errors(cityscapes_like_root):
    with pytest.raises(ValueError, match='paint_order'):
        CBNetInstanceMIoUMetric(paint_order='random')
    metric = CBNetInstanceMIoUMetric()
    metric.dataset_meta = dict(classes=CLASSES)
    sample = dict(img_id=0, ori_shape=(4, 4), pred_instances={})
    with pytest.raises(KeyError, match='instances'):
        metric.process({}, [sample])
    metric = CBNetInstanceMIoUMetric(
        ann_file=osp.join(cityscapes_like_root, ANN))
    metric.dataset_meta = dict(classes=CLASSES)
    with pytest.raises(KeyError, match='999'):
        metric.process({}, [dict(sample, img_id=999)])
    with pytest.raises(ValueError, match='rescale'):
        metric.pred_map(dict(masks=torch.zeros(1, 2, 2, dtype=torch.bool),
                             labels=torch.zeros(1), scores=torch.ones(1)),
                        (4, 4))
