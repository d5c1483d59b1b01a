"""CBNetClassMapMetric and the class map: a COCO-label model scored on
the project's 8 classes. Checked against CocoMetric on predictions mapped
by hand (the independent reference), plus the map's own rules and bad
input."""
import numpy as np
import pytest
import torch
from mmdet.evaluation import CocoMetric
from mmdet.registry import METRICS
from mmengine.structures import InstanceData

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.datasets.voc_fog import CITYSCAPES_CLASSES
from cbnet_mmdet.evaluation import CBNetClassMapMetric
from cbnet_mmdet.utils import class_map as cm
from mmdet.structures import DetDataSample

COCO = cm.coco_classes()
C = {name: i for i, name in enumerate(COCO)}
S = {name: i for i, name in enumerate(CITYSCAPES_CLASSES)}
#: Ground truth of two images: (box, project class).
GT = [
    [([10, 10, 50, 60], 'person'), ([100, 20, 180, 90], 'car'),
     ([60, 70, 90, 120], 'rider')],
    [([5, 5, 40, 40], 'truck'), ([50, 50, 90, 99], 'car')],
]


def sample(i, boxes, scores, labels):
    return dict(
        img_id=i, ori_shape=(128, 200),
        instances=[dict(bbox=b, bbox_label=S[n], ignore_flag=0)
                   for b, n in GT[i]],
        pred_instances=dict(
            bboxes=torch.tensor(boxes, dtype=torch.float32).reshape(-1, 4),
            scores=torch.tensor(scores, dtype=torch.float32),
            labels=torch.tensor(labels, dtype=torch.long)))


def coco_predictions():
    """What a COCO model predicts: every object right, in COCO labels,
    the rider as a person, and a dog over the car at a higher score."""
    return [
        sample(0, [[10, 10, 50, 60], [100, 20, 180, 90], [60, 70, 90, 120],
                   [100, 20, 180, 90]],
               [0.9, 0.8, 0.7, 0.95],
               [C['person'], C['car'], C['person'], C['dog']]),
        sample(1, [[5, 5, 40, 40], [50, 50, 90, 99]], [0.6, 0.5],
               [C['truck'], C['car']]),
    ]


def hand_mapped():
    """The same predictions mapped by hand: each person also a rider, the
    dog dropped."""
    return [
        sample(0, [[10, 10, 50, 60], [100, 20, 180, 90], [60, 70, 90, 120],
                   [10, 10, 50, 60], [60, 70, 90, 120]],
               [0.9, 0.8, 0.7, 0.9, 0.7],
               [S['person'], S['car'], S['person'], S['rider'],
                S['rider']]),
        sample(1, [[5, 5, 40, 40], [50, 50, 90, 99]], [0.6, 0.5],
               [S['truck'], S['car']]),
    ]


def evaluate(metric, samples):
    metric.dataset_meta = dict(classes=CITYSCAPES_CLASSES)
    metric.process({}, samples)
    return metric.evaluate(len(samples))


def test_the_map_of_the_projects_classes():
    assert cm.class_sources(CITYSCAPES_CLASSES) == [
        C['person'], C['person'], C['car'], C['truck'], C['bus'],
        C['train'], C['motorcycle'], C['bicycle']]
    targets = cm.label_targets(CITYSCAPES_CLASSES)
    assert targets[C['person']] == [S['person'], S['rider']]
    assert targets[C['dog']] == []
    # VOC's names
    assert cm.class_sources(('motorbike', 'tvmonitor', 'sofa')) == [
        C['motorcycle'], C['tv'], C['couch']]
    assert cm.class_sources(('fog lamp', 'car')) == [None, C['car']]
    assert 'rider <- person' in cm.describe_map(CITYSCAPES_CLASSES)
    with pytest.raises(ValueError, match="'rider' is to be scored as "
                       "'pedestrian'"):
        cm.class_sources(('rider', ), aliases=dict(rider='pedestrian'))
    with pytest.raises(ValueError, match='given twice'):
        cm.resolve_classes(('car', 'car'))
    with pytest.raises(ValueError, match="or 'coco'"):
        cm.resolve_classes('voc')


def test_scores_as_cocometric_on_predictions_mapped_by_hand():
    wrapped = METRICS.build(dict(
        type='CBNetClassMapMetric', source_classes='coco',
        metric=dict(type='CocoMetric', metric='bbox')))
    got = evaluate(wrapped, coco_predictions())
    want = evaluate(CocoMetric(metric='bbox'), hand_mapped())
    assert got == want
    # person, car, truck 100 (the dog over the car dropped); rider 50:
    # its one rider found at rank 2, after a person box scored as a rider
    assert got['coco/bbox_mAP'] == pytest.approx((1 + 0.5 + 1 + 1) / 4)


def test_without_the_map_the_same_predictions_score_wrong():
    """The check above can fail: COCO labels read as dataset labels (car
    = 2 is 'car' by chance, truck = 7 is 'bicycle', no rider) score lower
    (the dog, label 16, is left out: CocoMetric has no such class)."""
    preds = coco_predictions()
    keep = preds[0]['pred_instances']['labels'] != C['dog']
    preds[0]['pred_instances'] = {
        k: v[keep] for k, v in preds[0]['pred_instances'].items()}
    plain = evaluate(CocoMetric(metric='bbox'), preds)
    assert plain['coco/bbox_mAP'] < 0.8


def test_data_samples_and_masks_are_mapped_alike():
    metric = CBNetClassMapMetric(metric=dict(type='CocoMetric',
                                             metric='bbox'))
    metric.dataset_meta = dict(classes=CITYSCAPES_CLASSES)
    masks = torch.zeros(3, 4, 4, dtype=torch.bool)
    masks[0, 0, 0] = masks[1, 1, 1] = masks[2, 2, 2] = True
    pred = dict(bboxes=torch.arange(12.).reshape(3, 4),
                scores=torch.tensor([0.9, 0.8, 0.7]),
                labels=torch.tensor([C['person'], C['dog'], C['bus']]),
                masks=masks)
    out = metric.map_instances(pred)
    assert out['labels'].tolist() == [S['person'], S['bus'], S['rider']]
    assert out['scores'].tolist() == pytest.approx([0.9, 0.7, 0.9])
    assert out['masks'][2, 0, 0] and out['masks'][1, 2, 2]
    empty = metric.map_instances(dict(
        bboxes=torch.zeros(0, 4), scores=torch.zeros(0),
        labels=torch.zeros(0, dtype=torch.long)))
    assert len(empty['labels']) == 0 and empty['bboxes'].shape == (0, 4)
    # a DetDataSample as the evaluator may hand it
    ds = DetDataSample(metainfo=dict(img_id=0, ori_shape=(8, 8)))
    ds.pred_instances = InstanceData(**{k: v for k, v in pred.items()
                                        if k != 'masks'})
    ds.set_field([], 'instances', field_type='metainfo')
    metric.process({}, [ds])
    assert len(metric.metric.results) == 1


def test_bad_input_is_refused():
    with pytest.raises(TypeError, match='metric config dict'):
        CBNetClassMapMetric(metric='CocoMetric')
    metric = CBNetClassMapMetric(metric=dict(type='CocoMetric'))
    with pytest.raises(RuntimeError, match='dataset_meta is not set'):
        metric.map_instances(dict(labels=torch.tensor([0])))
    with pytest.raises(ValueError, match="no 'classes'"):
        metric.dataset_meta = dict()
    metric.dataset_meta = dict(classes=CITYSCAPES_CLASSES)
    with pytest.raises(ValueError, match='outside the model.s 80 source'):
        metric.map_instances(dict(labels=torch.tensor([80]),
                                  scores=torch.ones(1)))


def test_a_class_no_source_feeds_is_warned(monkeypatch):
    from mmengine.logging import MMLogger
    logger = MMLogger.get_instance('class_map_test')
    warned = []
    monkeypatch.setattr(logger, 'warning', warned.append)
    monkeypatch.setattr(MMLogger, 'get_current_instance',
                        classmethod(lambda cls: logger))
    metric = CBNetClassMapMetric(metric=dict(type='CocoMetric'))
    metric.dataset_meta = dict(classes=('car', 'fog lamp'))
    assert warned and "['fog lamp']" in warned[0]
    assert np.array_equal(metric._table[C['car']].numpy(), [0])
