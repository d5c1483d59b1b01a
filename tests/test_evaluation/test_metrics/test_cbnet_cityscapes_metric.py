"""The official Cityscapes instance AP (cityscapesScripts through
MMDetection's CityScapesMetric) on the generated stand-in, whose gtFine is
in the benchmark's format: its ground truth, read here from the
``*_gtFine_instanceIds.png`` files themselves, scores 100 as a prediction;
a foggy image finds the same ground truth; what cannot be scored is
refused naming the file."""
import glob
import os
import os.path as osp
import shutil

import numpy as np
import pytest
import torch
from cityscapesscripts.helpers.labels import id2label
from mmdet.registry import METRICS
from mmengine.config import Config
from PIL import Image

import cbnet_mmdet  # noqa: F401  (registers the metric)
from cbnet_mmdet.evaluation import CBNetCityScapesMetric
from cbnet_mmdet.evaluation.metrics.cbnet_cityscapes_metric import \
    ground_truth_file

CLASSES = ('person', 'rider', 'car', 'truck', 'bus', 'train', 'motorcycle',
           'bicycle')
ROOT = osp.dirname(osp.dirname(osp.dirname(osp.dirname(
    osp.abspath(__file__)))))


def val_images(root):
    return sorted(glob.glob(osp.join(root, 'leftImg8bit', 'val', '*',
                                     '*_leftImg8bit.png')))


def clear_gt(img_path):
    """gtFine/val/CITY/STEM_gtFine_instanceIds.png of a clear image."""
    folder = osp.dirname(img_path).replace(
        osp.join('leftImg8bit', 'val'), osp.join('gtFine', 'val'))
    return osp.join(folder, osp.basename(img_path).replace(
        '_leftImg8bit.png', '_gtFine_instanceIds.png'))


def gt_as_prediction(img_path, drop=0):
    """The instances of the image's instanceIds.png (labelId * 1000 + k)
    as a model's prediction, score 1; ``drop`` leaves out the largest."""
    gt = clear_gt(img_path)
    ids = np.array(Image.open(gt))
    masks, labels = [], []
    for value in np.unique(ids):
        if value < 1000:
            continue  # no instance (crowd regions and stuff)
        name = id2label[int(value) // 1000].name
        masks.append(ids == value)
        labels.append(CLASSES.index(name))
    # the largest first: the benchmark ignores regions under 100 px
    order = sorted(range(len(masks)), key=lambda i: -masks[i].sum())
    masks = [masks[i] for i in order][drop:]
    labels = [labels[i] for i in order][drop:]
    h, w = ids.shape
    return dict(
        img_path=img_path,
        pred_instances=dict(
            masks=torch.from_numpy(np.array(masks, bool).reshape(-1, h, w)),
            labels=torch.tensor(labels, dtype=torch.long),
            scores=torch.ones(len(labels)),
            bboxes=torch.zeros(len(labels), 4))), len(masks)


def score(samples):
    metric = CBNetCityScapesMetric()
    metric.dataset_meta = dict(classes=CLASSES)
    metric.process({}, samples)
    return metric.compute_metrics(metric.results)


def test_ground_truth_as_prediction_scores_100(cityscapes_like_root):
    samples, count = [], 0
    for path in val_images(cityscapes_like_root):
        sample, n = gt_as_prediction(path)
        samples.append(sample)
        count += n
    assert count > 0  # the stand-in has instances to score
    result = score(samples)
    assert result['mAP'] == pytest.approx(1.0)
    assert result['AP@50'] == pytest.approx(1.0)
    # a missed instance per image lowers it: the score is real
    fewer = [gt_as_prediction(p, drop=1)[0]
             for p in val_images(cityscapes_like_root)]
    assert score(fewer)['mAP'] < 1.0


def test_foggy_images_find_the_clear_ground_truth(cityscapes_like_root):
    clear = val_images(cityscapes_like_root)[0]
    foggy = clear.replace('leftImg8bit', 'leftImg8bit_foggy', 1).replace(
        '_leftImg8bit.png', '_leftImg8bit_foggy_beta_0.02.png')
    expected = clear_gt(clear)
    assert ground_truth_file(clear) == expected == ground_truth_file(foggy)
    assert osp.isfile(expected)
    assert ground_truth_file(foggy, '/data/gtFine/val') == osp.join(
        '/data/gtFine/val', osp.basename(osp.dirname(clear)),
        osp.basename(expected))
    sample, _ = gt_as_prediction(clear)
    sample['img_path'] = foggy  # MMDet's own found no file for it
    assert score([sample])['mAP'] == pytest.approx(1.0)


def test_what_cannot_be_scored_is_refused(cityscapes_like_root, tmp_path):
    root = tmp_path / 'cs'
    shutil.copytree(cityscapes_like_root, root)
    path = val_images(str(root))[0]
    sample, _ = gt_as_prediction(path)
    gt = ground_truth_file(path)
    os.remove(gt)
    with pytest.raises(FileNotFoundError,
                       match=f'{path}: its ground truth {gt} is missing'):
        score([sample])
    boxes = dict(sample, pred_instances=dict(
        labels=torch.zeros(0, dtype=torch.long), scores=torch.zeros(0),
        bboxes=torch.zeros(0, 4)))
    with pytest.raises(ValueError, match='the prediction has no masks'):
        score([boxes])
    with pytest.raises(ValueError, match='not a Cityscapes image name'):
        ground_truth_file('/x/val/city/photo.jpg')


@pytest.mark.parametrize('base', ['cityscapes_instance.py',
                                  'foggy_cityscapes_instance.py'])
def test_cityscapes_configs_keep_the_official_metric(base):
    cfg = Config.fromfile(osp.join(ROOT, 'configs', '_base_', 'datasets',
                                   base))
    for evaluators in (cfg.val_evaluator, cfg.test_evaluator):
        types = [e['type'] for e in evaluators]
        assert types == ['CocoMetric', 'CBNetInstanceMIoUMetric',
                         'CBNetCityScapesMetric'], types
    assert isinstance(METRICS.build(cfg.val_evaluator[2]),
                      CBNetCityScapesMetric)
