"""Per-model score calibration (cbnet_serving.calibration) and the pooled-AP
dip it explains.

A stream where neither model ever gives a worse answer than the other, and
yet the mix scores below both: the edge model answers every frame with the
object at score 0.9 and a false positive at 0.8, the server with the
object at 0.5 and a false positive at 0.1. Alone each ranks all its
objects above all its false positives (AP 100); mixed, the edge model's
false positives outrank the server's objects (pycocotools, called
directly, is the reference). Mapping each model's scores onto precision
removes the dip.
"""
import json

import numpy as np
import pytest
from serving_helpers import cocoeval_ap
from tool_helpers import load_tool

from cbnet_serving.calibration import (ScoreCalibration, coco_boxes,
                                       cross_fitted, match)
from cbnet_serving.offload import offload_curve, stream_annotations

CLASSES = ['person', 'car']
N = 8  # images; each is in the stream clear and foggy
H, W = 60, 80
FRAMES = [f'{c}/s{i}_leftImg8bit{s}.png' for i in range(1, N + 1)
          for c, s in (('clear', ''), ('fog', '_foggy_beta_0.02'))]
OBJECT = [10, 10, 40, 30]  # x1 y1 x2 y2, the car of every image
ELSEWHERE = [50, 35, 75, 55]  # a false positive, IoU 0 with it


def annotations():
    images = [dict(id=i, file_name=f's{i}_leftImg8bit.png', height=H,
                   width=W) for i in range(1, N + 1)]
    x1, y1, x2, y2 = OBJECT
    anns = [dict(id=i, image_id=i, category_id=2, iscrowd=0,
                 bbox=[x1, y1, x2 - x1, y2 - y1],
                 area=(x2 - x1) * (y2 - y1)) for i in range(1, N + 1)]
    return dict(images=images, annotations=anns,
                categories=[dict(id=1, name='person'),
                            dict(id=2, name='car')])


def answer(hit, miss):
    """The object at score ``hit`` and a false positive at ``miss``."""
    return dict(labels=[1, 1], scores=[hit, miss],
                bboxes=[OBJECT, ELSEWHERE])


EDGE, SERVER = answer(0.9, 0.8), answer(0.5, 0.1)


def write_run(folder, mode, pred):
    folder.mkdir()
    with open(folder / 'results.jsonl', 'w') as f:
        for frame in FRAMES:
            f.write(json.dumps(dict(
                frame=frame, where='local' if mode == 'local' else 'server',
                reason='', transmission=0.4 if 'foggy' in frame else 0.9,
                local_top_score=0.9, seconds=1.0, prediction=pred)) + '\n')
    json.dump(dict(local=dict(classes=CLASSES),
                   server=None if mode == 'local' else
                   dict(classes=CLASSES)), open(folder / 'run.json', 'w'))
    return str(folder)


@pytest.fixture
def runs(tmp_path):
    ann = tmp_path / 'ann.json'
    json.dump(annotations(), open(ann, 'w'))
    return dict(ann=str(ann), local=write_run(tmp_path / 'local', 'local',
                                              EDGE),
                server=write_run(tmp_path / 'server', 'server', SERVER),
                tmp=tmp_path)


def test_match_is_greedy_by_score_once_per_object():
    gt = {'car': np.array([OBJECT], float)}
    near = [12, 10, 40, 30]  # IoU 28/30 with the object
    pred = dict(labels=[1, 1, 0, 1], scores=[0.3, 0.7, 0.9, 0.5],
                bboxes=[OBJECT, near, OBJECT, ELSEWHERE])
    # the 0.7 box takes the object (highest score first), the exact box
    # at 0.3 comes too late; the person box has no person to match
    assert match(pred, gt, CLASSES).tolist() == [False, True, False, False]
    assert not match(pred, gt, CLASSES, iou_thr=0.95)[1]
    with pytest.raises(ValueError, match='out of range'):
        match(dict(pred, labels=[1, 1, 2, 1]), gt, CLASSES)
    with pytest.raises(ValueError, match='2 labels, 1 scores'):
        match(dict(labels=[1, 1], scores=[0.5], bboxes=[OBJECT, OBJECT]),
              gt, CLASSES)


def test_fit_is_the_isotonic_precision_of_the_scores():
    gt = [{'car': np.array([OBJECT], float)}] * 4
    # scores 0.2 (miss), 0.4 (hit), 0.6 (miss), 0.8 (hit): pool-adjacent-
    # violators merges 0.4 and 0.6 into 0.5
    preds = [dict(labels=[1], scores=[s], bboxes=[b]) for s, b in
             ((0.2, ELSEWHERE), (0.4, OBJECT), (0.6, ELSEWHERE),
              (0.8, OBJECT))]
    calib = ScoreCalibration.fit(preds, gt, CLASSES, min_detections=1)
    xs, ys = calib.maps['car']
    assert xs == [0.2, 0.4, 0.6, 0.8]
    assert ys == pytest.approx([0.0, 0.5, 0.5, 1.0])
    assert calib.precision('car', [0.3, 0.9]) == pytest.approx([0.25, 1.0])
    # a class with too few detections uses the map of all classes
    calib = ScoreCalibration.fit(preds, gt, CLASSES, min_detections=5)
    assert set(calib.maps) == {'*'}
    out = calib.apply(dict(labels=[1, 1], scores=[0.6, 0.4],
                           bboxes=[OBJECT, OBJECT]), CLASSES)
    # equal precision: the model's own order is kept, barely
    assert out['scores'][0] > out['scores'][1]
    assert out['scores'] == pytest.approx([0.5, 0.5], abs=1e-5)
    with pytest.raises(ValueError, match='no detections'):
        ScoreCalibration.fit([dict(labels=[], scores=[], bboxes=[])],
                             gt[:1], CLASSES)
    with pytest.raises(ValueError, match='2 predictions for 1 images'):
        ScoreCalibration.fit(preds[:2], gt[:1], CLASSES)


def test_cross_fitting_never_grades_an_image_on_its_own_answer():
    gt = annotations()
    # images 1..4 are answered right at 0.9, images 5..8 wrong at 0.9:
    # each image's calibrated score comes from the OTHER half's answers
    preds = [answer(0.9, 0.1) if i <= 4 else
             dict(labels=[1], scores=[0.9], bboxes=[ELSEWHERE])
             for i in range(1, N + 1)]
    out, fits = cross_fitted(preds, gt, CLASSES, min_detections=1)
    assert set(fits) == {'half 0', 'half 1'}
    boxes = coco_boxes(gt)
    assert len(boxes) == N and boxes[0]['car'].tolist() == [OBJECT]
    for i, (p, q) in enumerate(zip(preds, out)):
        assert len(q['scores']) == len(p['scores'])
        assert all(0 <= s <= 1 + 1e-5 for s in q['scores'])
    with pytest.raises(ValueError, match='at least 2 images'):
        cross_fitted(preds[:1], dict(gt, images=gt['images'][:1]), CLASSES)


def test_the_mixed_stream_dips_below_both_models_and_calibration_lifts_it(
        runs):
    gt = stream_annotations(runs['ann'], FRAMES)
    foggy = ['foggy' in f for f in FRAMES]
    mixed = [SERVER if f else EDGE for f in foggy]
    # the reference: pycocotools on the three streams
    assert cocoeval_ap(gt, with_masks([EDGE] * len(FRAMES)), 'bbox') == \
        pytest.approx(100)
    assert cocoeval_ap(gt, with_masks([SERVER] * len(FRAMES)), 'bbox') == \
        pytest.approx(100)
    dip = cocoeval_ap(gt, with_masks(mixed), 'bbox')
    assert dip < 90

    kw = dict(thresholds=[0.6], random_seeds=(0, ), metrics=('bbox', ),
              progress=lambda *_: None)
    raw = {r['policy']: r for r in offload_curve(
        runs['local'], runs['server'], runs['ann'], **kw)['rows']}
    haze = raw['haze: transmission < 0.6']
    assert haze['offloaded'] == {'clear': 0.0, '0.02': 1.0}
    assert haze['bbox_mAP'] == pytest.approx(dip, abs=0.1)
    # each condition alone is answered by one model: no dip there
    assert haze['condition_ap']['0.02']['bbox_mAP'] == pytest.approx(100)
    assert haze['condition_ap']['clear']['bbox_mAP'] == pytest.approx(100)

    res = offload_curve(runs['local'], runs['server'], runs['ann'],
                        calibrate=True, **kw)
    cal = {r['policy']: r for r in res['rows']}
    assert res['calibrated'] and set(res['calibration']) == {'local',
                                                             'server'}
    for name in ('always local', 'always server',
                 'haze: transmission < 0.6'):
        assert cal[name]['bbox_mAP'] == pytest.approx(100), name
    with pytest.raises(ValueError, match='auto run'):
        offload_curve(runs['local'], runs['server'], runs['ann'],
                      calibrate=True, auto_dir=runs['local'], **kw)


def with_masks(preds):
    """cocoeval_ap's prediction fields (masks unused for boxes)."""
    return [dict(p, masks=[None] * len(p['labels'])) for p in preds]


def test_offload_eval_calibrate_option(runs):
    tool = load_tool('projects/edge_serving/tools/offload_eval.py')
    out = runs['tmp'] / 'out'
    tool.main([runs['local'], runs['server'], '--ann', runs['ann'],
               '--thresholds', '0.6', '--boxes-only', '--calibrate',
               '--out-dir', str(out)])
    record = json.loads((out / 'offload.json').read_text())
    assert record['calibrated'] is True
    md = (out / 'offload.md').read_text()
    assert md.startswith('Scores calibrated per model')
    assert 'box AP 0.02' in md
