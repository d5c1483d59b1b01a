"""The metrics the lab reports, named once.

Label -> (key in the results of MMDet's ``CocoMetric`` (prefix ``coco``)
or our ``CBNetInstanceMIoUMetric`` (prefix ``cityscapes``), scale to the
percent the tables print, as the paper does).
"""
from typing import Tuple

METRICS = {
    'box AP': ('coco/bbox_mAP', 100.0),
    'box AP50': ('coco/bbox_mAP_50', 100.0),
    'box AP_s': ('coco/bbox_mAP_s', 100.0),
    'box AP_m': ('coco/bbox_mAP_m', 100.0),
    'box AP_l': ('coco/bbox_mAP_l', 100.0),
    'mask AP': ('coco/segm_mAP', 100.0),
    'mask AP50': ('coco/segm_mAP_50', 100.0),
    'mIoU': ('cityscapes/mIoU', 100.0),
    'AR@100': ('coco/AR@100', 100.0),
    'AR@300': ('coco/AR@300', 100.0),
    'AR@1000': ('coco/AR@1000', 100.0),
}


def columns(*labels: str) -> Tuple[Tuple[str, str, float], ...]:
    """``(label, key, scale)`` of each label, in order.

    Raises:
        KeyError: a label that is not in :data:`METRICS`.
    """
    return tuple((label, ) + METRICS[label] for label in labels)
