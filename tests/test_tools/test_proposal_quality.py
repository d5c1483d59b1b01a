"""tools/analysis_tools/proposal_quality.py: the statistics against boxes
whose IoUs are known, and a run on the demo model."""
import json

import pytest
import torch
from mmdet.structures import DetDataSample
from mmengine.structures import InstanceData
from tool_helpers import DEMO, demo_checkpoint, load_tool


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
    tool = load_tool('analysis_tools/proposal_quality.py')
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
    r = tool.proposal_quality(model, dataset)
    assert r['images'] == 3 and r['gt_boxes'] == 2
    assert r['proposals_per_image'] == pytest.approx(5 / 3)
    assert r['recall'] == {'0.5': 1.0, '0.7': 1.0, '0.9': 0.5}
    assert r['mean_best_iou'] == pytest.approx((1.0 + 0.8) / 2)
    # per proposal best IoU: 1, 0.5, 0, 0.8, 0
    assert r['positive_share'] == pytest.approx(
        {'0.5': 3 / 5, '0.6': 2 / 5, '0.7': 2 / 5})
    assert r == tool.proposal_quality(model, dataset + dataset[:1],
                                      max_images=3)


@pytest.mark.slow  # builds and runs the demo model on 2 images
def test_demo_model_run(tmp_path, cityscapes_like_root):
    tool = load_tool('analysis_tools/proposal_quality.py')
    ckpt = demo_checkpoint(str(tmp_path / 'demo.pth'))
    out = tmp_path / 'p.json'
    tool.main([DEMO, ckpt, '--names', 'demo', '--data-root',
               cityscapes_like_root, '--max-images', '2', '--out', str(out)])
    r = json.loads(out.read_text())['results']['demo']
    assert r['images'] == 2 and r['gt_boxes'] > 0
    assert 0 < r['proposals_per_image'] <= 300  # the demo's test k
    assert 0 <= r['recall']['0.9'] <= r['recall']['0.5'] <= 1


def test_runs_are_read_from_training_folders(tmp_path):
    tool = load_tool('analysis_tools/proposal_quality.py')
    run = tmp_path / 'run'
    run.mkdir()
    (run / 'model.py').write_text('x = 1\n')
    ckpt = run / 'iter_600.pth'
    ckpt.write_bytes(b'')
    (run / 'last_checkpoint').write_text('/elsewhere/iter_600.pth')
    args = tool.parse_args(['--runs', str(run)])
    pairs = tool.models_of(args)
    assert pairs == [(str(run / 'model.py'), str(ckpt))]
    assert tool.default_names(args, pairs) == [f'{tmp_path.name}/run']
    (run / 'other.py').write_text('x = 2\n')
    with pytest.raises(SystemExit, match='one config'):
        tool.models_of(tool.parse_args(['--runs', str(run)]))


def test_bad_arguments(tmp_path):
    tool = load_tool('analysis_tools/proposal_quality.py')
    with pytest.raises(SystemExit):
        tool.main([])
    with pytest.raises(SystemExit):
        tool.main([DEMO])  # no checkpoint
    with pytest.raises(SystemExit, match='checkpoint not found'):
        tool.main([DEMO, str(tmp_path / 'missing.pth')])
    ckpt = tmp_path / 'c.pth'
    ckpt.write_bytes(b'')
    with pytest.raises(SystemExit, match='2 names for 1 models'):
        tool.main([DEMO, str(ckpt), '--names', 'a', 'b'])
    with pytest.raises(SystemExit, match='share a name'):
        tool.main([DEMO, str(ckpt), DEMO, str(ckpt)])
