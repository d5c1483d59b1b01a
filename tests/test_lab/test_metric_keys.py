"""cbnet_lab.metric_keys: one table of the reported metrics."""
import pytest

from cbnet_lab import ap_drop, recipe_comparison, robustness
from cbnet_lab.metric_keys import METRICS, columns


def test_columns_keep_the_order_and_refuse_unknown_labels():
    assert columns('mIoU', 'box AP') == (('mIoU', 'cityscapes/mIoU', 100.0),
                                         ('box AP', 'coco/bbox_mAP', 100.0))
    with pytest.raises(KeyError):
        columns('mask AP75')


def test_every_table_of_the_lab_reads_the_one_table():
    used = (recipe_comparison.DETECTION_COLUMNS +
            recipe_comparison.PROPOSAL_COLUMNS + ap_drop.COLUMNS)
    for label, key, scale in used:
        assert METRICS[label] == (key, scale)
    for label, key in robustness.SUMMARY_METRICS:
        assert METRICS[label][0] == key
