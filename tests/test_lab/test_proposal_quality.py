"""cbnet_lab.proposal_quality: the statistics against boxes whose IoUs are
known (the command line, tools/analysis_tools/proposal_quality.py, is
tested in tests/test_tools/test_proposal_quality_cli.py)."""
import pytest
import torch
from mmdet.structures import DetDataSample
from mmengine.structures import InstanceData

from cbnet_lab.proposal_quality import proposal_quality


class _FakeModel:
    """An RPN that proposes given boxes (in the resized image)."""

    def __init__(self, proposals):
        self.proposals = proposals

    def data_preprocessor(self, data, training):
        return dict(inputs=None, data_samples=data)

    def extract_feat(self, inputs):
        return None

    @property
    def rpn_head(self):
        return self

    def predict(self, feats, samples, rescale):
        return [InstanceData(bboxes=self.proposals[samples[0].img_id])]


def _sample(img_id, gt, scale=(2.0, 2.0)):
    s = DetDataSample(metainfo=dict(scale_factor=scale))
    s.img_id = img_id
    s.gt_instances = InstanceData(bboxes=torch.tensor(gt, dtype=torch.float))
    return s


def test_statistics_against_known_ious():
    # image 0: GT (0,0,10,10) at scale 2 -> (0,0,20,20); proposals: the
    # box itself (IoU 1), half of it (IoU 0.5) and a miss (IoU 0)
    # image 1: GT (0,0,5,5) -> (0,0,10,10); proposal (0,0,10,8): IoU 0.8
    # image 2: no GT, one proposal (all background)
    dataset = [_sample(0, [[0, 0, 10, 10]]), _sample(1, [[0, 0, 5, 5]]),
               _sample(2, torch.zeros(0, 4))]
    model = _FakeModel({
        0: torch.tensor([[0., 0., 20., 20.], [0., 0., 20., 10.],
                         [50., 50., 60., 60.]]),
        1: torch.tensor([[0., 0., 10., 8.]]),
        2: torch.tensor([[0., 0., 4., 4.]]),
    })
    r = proposal_quality(model, dataset)
    assert r['images'] == 3 and r['gt_boxes'] == 2
    assert r['proposals_per_image'] == pytest.approx(5 / 3)
    assert r['recall'] == {'0.5': 1.0, '0.7': 1.0, '0.9': 0.5}
    assert r['mean_best_iou'] == pytest.approx((1.0 + 0.8) / 2)
    # per proposal best IoU: 1, 0.5, 0, 0.8, 0
    assert r['positive_share'] == pytest.approx(
        {'0.5': 3 / 5, '0.6': 2 / 5, '0.7': 2 / 5})
    assert r == proposal_quality(model, dataset + dataset[:1],
                                 max_images=3)
