"""An oracle detector and a test config around it, for the evaluation
tools (AP drop, robustness) run through MMEngine's Runner; a seeded
MobileNetV2 weights file where the pretrained configs look for their
trunk (``fake_weights``, the pretrained sets' end-to-end tests); a tiny
clear COCO street set beside a tiny VOC fog folder (``street_and_fog``,
the transfer sets' end-to-end tests)."""
import os
import os.path as osp

import pytest
import torch
from mmdet.models.backbones import MobileNetV2
from mmdet.models.detectors.base import BaseDetector
from mmdet.registry import MODELS
from mmengine.config import Config
from mmengine.structures import InstanceData
from torch import nn

from cbnet_tools import pretrained as pt

ROOT = osp.join(osp.dirname(__file__), '..', '..')
DATASET_CFG = osp.join(ROOT, 'configs', '_base_', 'datasets',
                       'cityscapes_instance.py')
#: (img_path, input Tensor[3, H, W]) of every image the oracle saw.
SEEN = []


@MODELS.register_module(name='_CBNetTestOracle', force=True)
class _Oracle(BaseDetector):
    """Predicts the ground truth of each image; records what it is given.

    ``drop_on_foggy`` ({beta as str: n}): on the foggy images of that beta
    the first ``n`` instances (annotation order) are left out, so the AP
    drop is a known non-zero number. ``drop_class``: the instances of this
    label are left out on every image. Boxes only where the ground truth
    has no masks (VOC real-fog sets).
    """

    def __init__(self, data_preprocessor=None, drop_on_foggy=None,
                 drop_class=None):
        super().__init__(data_preprocessor=data_preprocessor)
        self.dummy = nn.Parameter(torch.zeros(1))
        self.drop_on_foggy = dict(drop_on_foggy or {})
        self.drop_class = drop_class

    def predict(self, batch_inputs, batch_data_samples, rescale=True):
        for img, sample in zip(batch_inputs, batch_data_samples):
            SEEN.append((sample.img_path, img.clone()))
            gt = sample.gt_instances
            for beta, num in self.drop_on_foggy.items():
                if sample.img_path.endswith(f'_foggy_beta_{beta}.png'):
                    gt = gt[num:]
            if self.drop_class is not None:
                gt = gt[gt.labels != self.drop_class]
            pred = InstanceData(
                bboxes=getattr(gt.bboxes, 'tensor', gt.bboxes),
                labels=gt.labels,
                scores=torch.ones(len(gt)))
            if 'masks' in gt:
                pred.masks = gt.masks.to_tensor(torch.bool, 'cpu')
            sample.pred_instances = pred
        return batch_data_samples

    def loss(self, *args, **kwargs):
        raise NotImplementedError

    def _forward(self, *args, **kwargs):
        raise NotImplementedError

    def extract_feat(self, *args, **kwargs):
        raise NotImplementedError


@pytest.fixture
def make_oracle(cityscapes_like_root, tmp_path):
    """Factory of :func:`oracle` setups, ``drop_on_foggy`` as the model's."""
    return lambda drop_on_foggy=None: _oracle_setup(
        cityscapes_like_root, tmp_path, drop_on_foggy)


@pytest.fixture
def oracle(make_oracle):
    """The Cityscapes dataset config with the oracle on the tiny set (no
    resize), as a file, with a checkpoint; ``seen`` is cleared."""
    return make_oracle()


def _oracle_setup(cityscapes_like_root, tmp_path, drop_on_foggy):
    root = cityscapes_like_root + '/'
    cfg = Config.fromfile(DATASET_CFG)
    cfg.default_scope = 'mmdet'
    cfg.model = dict(type='_CBNetTestOracle',
                     data_preprocessor=dict(type='DetDataPreprocessor'),
                     drop_on_foggy=drop_on_foggy)
    cfg.test_cfg = dict(type='TestLoop')
    ds = cfg.test_dataloader.dataset
    ds.data_root = root
    ds.pipeline = [p for p in ds.pipeline if p['type'] != 'Resize']
    cfg.test_dataloader.update(num_workers=0, persistent_workers=False)
    for m in cfg.test_evaluator:
        if 'ann_file' not in m:
            continue  # the official Cityscapes metric reads gtFine
        m['ann_file'] = root + 'annotations/' \
            'instancesonly_filtered_gtFine_val.json'
        if m['type'] == 'CBNetInstanceMIoUMetric':
            m['ignore_crowd'] = True  # the oracle predicts no crowds
    cfg.log_level = 'WARNING'
    ckpt = str(tmp_path / 'oracle.pth')
    torch.save({'state_dict': {'dummy': torch.zeros(1)}}, ckpt)
    cfg_file = str(tmp_path / 'oracle_cfg.py')
    cfg.dump(cfg_file)
    SEEN.clear()
    return dict(cfg_file=cfg_file, ckpt=ckpt, seen=SEEN)


@pytest.fixture
def fake_weights(tmp_path, monkeypatch):
    """A seeded MobileNetV2 saved where the configs look for the trunk."""
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'weights'))
    os.makedirs(pt.pretrained_dir())
    torch.manual_seed(1)
    model = MobileNetV2()
    torch.save(dict(state_dict=model.state_dict()),
               pt.pretrained_path('mobilenet_v2'))
    return model.state_dict()


@pytest.fixture
def street_and_fog(cityscapes_like_root, tmp_path):
    """A tiny clear COCO street set (through tools/dataset_converters/
    coco_street.py) and a tiny VOC fog folder: their two paths."""
    from set_helpers import fake_coco
    from tool_helpers import load_tool

    from cbnet_tools.synthetic.voc_folder import tiny_fog_folder
    fake_coco(cityscapes_like_root, str(tmp_path / 'coco'))
    load_tool('dataset_converters/coco_street.py').main(
        [str(tmp_path / 'coco'), str(tmp_path / 'street')])
    tiny_fog_folder(str(tmp_path / 'fog'), num_images=10)
    return str(tmp_path / 'street'), str(tmp_path / 'fog')
