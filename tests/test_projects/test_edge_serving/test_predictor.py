"""``Predictor``: MMDet's collate notice dropped while it builds its
inferencer, every other record kept."""
import logging
import os.path as osp

import pytest
from mmdet.apis import DetInferencer
from mmengine.logging import print_log

from cbnet_serving.predictor import COLLATE_NOTICE, Predictor

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.dirname(
    osp.abspath(__file__)))))
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')


@pytest.fixture
def records(log_messages):
    return log_messages()


def test_mmdet_inferencer_logs_the_notice(records):
    """The reference: MMDetection's own inferencer logs it (if this fails,
    MMDet stopped logging it and the filter has nothing left to drop)."""
    DetInferencer(model=DEMO, device='cpu', show_progress=False)
    assert any(COLLATE_NOTICE in r for r in records)


def test_predictor_drops_only_the_notice(records):
    predictor = Predictor(DEMO)
    assert not any(COLLATE_NOTICE in r for r in records)
    assert predictor.info()['weights'] == 'random init'
    # the filter is gone once the inferencer is built: nothing else lost
    print_log(COLLATE_NOTICE + ' (after)', logger='current',
              level=logging.WARNING)
    assert records[-1].startswith(COLLATE_NOTICE)
