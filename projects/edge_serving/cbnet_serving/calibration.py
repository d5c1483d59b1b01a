"""Per-model score calibration for a stream that mixes two detectors.

COCO AP pools a class's detections over every image of the stream and
ranks them by score. When the router keeps some frames on the edge model
and sends the others to the server, one ranking holds the scores of two
models, and a score of 0.8 need not mean the same for both: an
over-confident edge model's false positives then outrank the server's
true positives, and the stream's pooled AP falls below what either
model scores alone, although no frame got a worse answer
(``tests/test_projects/test_edge_serving/test_calibration.py`` builds
such a stream).

The remedy here maps each model's scores, per class, onto the precision
they stand for: the fraction of its detections at that score that match
an object (IoU >= 0.5, each object matched once, highest score first),
fitted by isotonic regression (:func:`scipy.optimize.isotonic_regression`,
non-decreasing in the score). After it a score means "this likely a true
positive" for either model, which is what a pooled ranking assumes.
Fitting on the frames that are then scored would grade a model on its own
answers: :func:`cross_fitted` fits on one half of the frames and applies
to the other, both ways.
"""
from typing import Dict, List, Optional, Sequence

import numpy as np

#: A class with fewer detections than this uses the model's map fitted on
#: all classes together (an isotonic fit on a handful of points is noise).
MIN_DETECTIONS = 20
#: Calibrated scores keep each model's own order among equal precisions:
#: the original score times this is added (far below the precision steps).
TIE_BREAK = 1e-6


def _iou(boxes: np.ndarray, gts: np.ndarray) -> np.ndarray:
    """IoU of ``(n, 4)`` x1y1x2y2 boxes with ``(m, 4)`` ones."""
    import torch
    from mmdet.structures.bbox import bbox_overlaps
    return bbox_overlaps(torch.as_tensor(boxes, dtype=torch.float32),
                         torch.as_tensor(gts, dtype=torch.float32)).numpy()


def match(pred: Dict, gt_boxes: Dict[str, np.ndarray],
          classes: Sequence[str], iou_thr: float = 0.5) -> np.ndarray:
    """Which detections of one image's prediction are true positives.

    Args:
        pred (dict): ``labels``, ``scores``, ``bboxes`` (x1y1x2y2), as
            route.py records them.
        gt_boxes (dict): class name -> ``(m, 4)`` x1y1x2y2 objects of the
            image (crowd regions left out).
        classes (Sequence[str]): the model's class names, its ``labels``
            index them.
        iou_thr (float): the IoU at which a detection matches an object.

    Returns:
        np.ndarray: bool per detection; in each class the detections are
        matched highest score first, each object at most once (COCO's
        greedy rule at one IoU).
    """
    labels = np.asarray(pred.get('labels', []), int)
    scores = np.asarray(pred.get('scores', []), float)
    boxes = np.asarray(pred.get('bboxes', []), float).reshape(-1, 4)
    if not len(labels) == len(scores) == len(boxes):
        raise ValueError(f'a prediction has {len(labels)} labels, '
                         f'{len(scores)} scores and {len(boxes)} boxes')
    if len(labels) and (labels.min() < 0 or labels.max() >= len(classes)):
        raise ValueError(f'label {labels.max()} out of range for '
                         f'{len(classes)} classes')
    hit = np.zeros(len(labels), bool)
    for c in np.unique(labels):
        gts = np.asarray(gt_boxes.get(classes[c], np.zeros((0, 4))),
                         float).reshape(-1, 4)
        idx = np.where(labels == c)[0]
        if not len(gts):
            continue
        idx = idx[np.argsort(-scores[idx], kind='stable')]
        iou = _iou(boxes[idx], gts)
        free = np.ones(len(gts), bool)
        for row, det in enumerate(idx):
            cand = np.where(free & (iou[row] >= iou_thr))[0]
            if len(cand):
                best = cand[np.argmax(iou[row][cand])]
                free[best] = False
                hit[det] = True
    return hit


class ScoreCalibration:
    """Score -> precision maps of one model, per class and pooled.

    Args:
        maps (dict): class name (or ``'*'`` for all classes) ->
            ``(scores, precisions)``, increasing knots of the isotonic fit.
    """

    def __init__(self, maps: Dict[str, tuple]):
        if '*' not in maps:
            raise ValueError("a calibration needs the pooled map '*'")
        self.maps = maps

    @classmethod
    def fit(cls, preds: Sequence[Dict], gts: Sequence[Dict],
            classes: Sequence[str], iou_thr: float = 0.5,
            min_detections: int = MIN_DETECTIONS) -> 'ScoreCalibration':
        """Fit on images' predictions ``preds`` and their objects ``gts``
        (one ``{class: boxes}`` per image, as :func:`match` takes)."""
        from scipy.optimize import isotonic_regression
        if len(preds) != len(gts):
            raise ValueError(f'{len(preds)} predictions for {len(gts)} '
                             'images')
        by_class: Dict[str, List] = {}
        for pred, gt in zip(preds, gts):
            hits = match(pred, gt, classes, iou_thr)
            for label, s, h in zip(pred.get('labels', []),
                                   pred.get('scores', []), hits):
                by_class.setdefault(classes[label], []).append((s, h))
        pooled = [p for v in by_class.values() for p in v]
        if not pooled:
            raise ValueError('no detections to calibrate on')

        def knots(pairs):
            s, h = np.asarray(pairs, float).T
            order = np.argsort(s, kind='stable')
            s, h = s[order], h[order]
            y = isotonic_regression(h, increasing=True).x
            # one knot per distinct score: the mean fit of its detections
            # (equal scores in a stable sort can get different fitted
            # values; means of consecutive runs keep the fit increasing)
            u, inv = np.unique(s, return_inverse=True)
            val = np.bincount(inv, weights=y) / np.bincount(inv)
            return u.tolist(), val.tolist()

        maps = {'*': knots(pooled)}
        for name, pairs in by_class.items():
            if len(pairs) >= min_detections:
                maps[name] = knots(pairs)
        return cls(maps)

    def precision(self, name: str, scores: Sequence[float]) -> np.ndarray:
        """The fitted precision at ``scores`` of class ``name`` (linear
        between knots, flat beyond them)."""
        xs, ys = self.maps.get(name, self.maps['*'])
        return np.interp(np.asarray(scores, float), xs, ys)

    def apply(self, pred: Dict, classes: Sequence[str]) -> Dict:
        """A copy of ``pred`` with calibrated ``scores`` (the model's own
        order kept among equal precisions)."""
        scores = np.asarray(pred.get('scores', []), float)
        labels = np.asarray(pred.get('labels', []), int)
        out = np.zeros(len(scores))
        for c in np.unique(labels):
            out[labels == c] = self.precision(classes[c],
                                              scores[labels == c])
        return dict(pred, scores=(out + TIE_BREAK * scores).tolist())

    def to_dict(self) -> Dict:
        return {k: dict(scores=v[0], precision=v[1])
                for k, v in self.maps.items()}


def coco_boxes(gt: Dict) -> List[Dict[str, np.ndarray]]:
    """``{class: (m, 4) x1y1x2y2}`` per image of a COCO instances dict, in
    its image order (crowd regions left out, as COCO ignores them)."""
    names = {c['id']: c['name'] for c in gt['categories']}
    per = {img['id']: {} for img in gt['images']}
    for a in gt['annotations']:
        if a.get('iscrowd', 0) or a['image_id'] not in per:
            continue
        x, y, w, h = a['bbox']
        per[a['image_id']].setdefault(names[a['category_id']],
                                      []).append([x, y, x + w, y + h])
    return [{k: np.asarray(v, float) for k, v in per[img['id']].items()}
            for img in gt['images']]


def cross_fitted(preds: Sequence[Dict], gt: Dict, classes: Sequence[str],
                 seed: int = 0,
                 min_detections: int = MIN_DETECTIONS) -> tuple:
    """Calibrate one model's predictions of every image of ``gt`` (COCO
    dict, same order) without grading any image on its own answers: the
    images are split in two seeded halves, each half's scores mapped with
    the calibration fitted on the other.

    Returns:
        tuple: (calibrated predictions, ``{'half 0': map, 'half 1': map}``
        of the fits, for the record).
    """
    n = len(gt['images'])
    if len(preds) != n:
        raise ValueError(f'{len(preds)} predictions for {n} images')
    if n < 2:
        raise ValueError('cross-fitting needs at least 2 images')
    boxes = coco_boxes(gt)
    half = np.zeros(n, int)
    half[np.random.default_rng(seed).permutation(n)[n // 2:]] = 1
    out: List[Optional[Dict]] = [None] * n
    fits = {}
    for h in (0, 1):
        train = np.where(half != h)[0]
        calib = ScoreCalibration.fit([preds[i] for i in train],
                                     [boxes[i] for i in train], classes,
                                     min_detections=min_detections)
        fits[f'half {h}'] = calib.to_dict()
        for i in np.where(half == h)[0]:
            out[i] = calib.apply(preds[i], classes)
    return out, fits
