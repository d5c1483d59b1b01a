import importlib.util
import json
from collections import Counter
import os.path as osp

import numpy as np
import pytest
import torch
from mmdet.models.detectors.base import BaseDetector
from mmdet.registry import MODELS
from mmengine.config import Config
from mmengine.structures import InstanceData
from torch import nn

from cbnet_mmdet.evaluation.ap_drop import (condition_cfg, drop_table,
                                            to_markdown)

ROOT = osp.join(osp.dirname(__file__), '..', '..')
CFG = osp.join(ROOT, 'configs', '_base_', 'datasets',
               'cityscapes_instance.py')
SEEN = []
#: Per fog density, how many instances of each image (the first ones, in
#: annotation order) the oracle leaves out on the foggy images: a known AP
#: drop, larger for the denser fog.
DROPPED = {'0.01': 1, '0.02': 2}


@MODELS.register_module(name='_CBNetTestOracle', force=True)
class _Oracle(BaseDetector):
    """Predicts the ground truth of each image, without the first
    ``DROPPED[beta]`` instances on the foggy images of that beta; records
    the image paths."""

    def __init__(self, data_preprocessor=None):
        super().__init__(data_preprocessor=data_preprocessor)
        self.dummy = nn.Parameter(torch.zeros(1))

    def predict(self, batch_inputs, batch_data_samples, rescale=True):
        for sample in batch_data_samples:
            SEEN.append(sample.img_path)
            gt = sample.gt_instances
            for beta, num in DROPPED.items():
                if sample.img_path.endswith(f'_foggy_beta_{beta}.png'):
                    gt = gt[num:]
            sample.pred_instances = InstanceData(
                bboxes=getattr(gt.bboxes, 'tensor', gt.bboxes),
                labels=gt.labels,
                scores=torch.ones(len(gt)),
                masks=gt.masks.to_tensor(torch.bool, 'cpu'))
        return batch_data_samples

    def loss(self, *args, **kwargs):
        raise NotImplementedError

    def _forward(self, *args, **kwargs):
        raise NotImplementedError

    def extract_feat(self, *args, **kwargs):
        raise NotImplementedError


def test_condition_cfg():
    cfg = Config.fromfile(CFG)
    foggy = condition_cfg(cfg, 0.01)
    assert foggy.test_dataloader.dataset.type == \
        'CBNetFoggyCityscapesDataset'
    assert foggy.test_dataloader.dataset.beta == 0.01
    assert cfg.test_dataloader.dataset.type == 'CBNetCityscapesDataset'
    clear = condition_cfg(foggy, None)
    assert clear.test_dataloader.dataset.type == 'CBNetCityscapesDataset'
    assert 'beta' not in clear.test_dataloader.dataset
    cfg.test_dataloader.dataset.type = 'CocoDataset'
    with pytest.raises(ValueError, match='CocoDataset'):
        condition_cfg(cfg, 0.02)


def test_drop_table_and_markdown():
    table = drop_table({
        'clear': {'coco/bbox_mAP': 0.5, 'coco/segm_mAP': 0.4,
                  'coco/segm_mAP_50': 0.6, 'cityscapes/mIoU': 0.35},
        'foggy': {'coco/bbox_mAP': 0.45, 'coco/segm_mAP': 0.37,
                  'coco/segm_mAP_50': -1.0, 'cityscapes/mIoU': 0.3},
    })
    clear, foggy = table['rows']
    assert clear['mask AP drop'] == 0.0
    assert foggy['mask AP drop'] == pytest.approx(3.0)
    assert foggy['mIoU drop'] == pytest.approx(5.0)
    assert foggy['mask AP50'] is None  # COCO's -1 is "undefined"
    md = to_markdown(table).splitlines()
    assert md[0].startswith('| condition | box AP | mask AP |')
    assert md[3].startswith('| foggy | 45.0 | 37.0 | - | 30.0 | 5.0 |')


def expected_ap(coco: dict, num_dropped: int) -> float:
    """COCO mAP (percent) of exact predictions (score 1, IoU 1 at every
    threshold) of all non-crowd instances but the first ``num_dropped`` of
    each image: per category with ground truth, the precision is 1 up to
    the recall ``m / n`` (``m`` of its ``n`` instances predicted) and 0
    beyond, so its AP is the share of COCO's 101 recall thresholds
    ``<= m / n`` (0 when ``m = 0``: no precision at all, not even at
    recall 0); the mean is over the categories with ground truth."""
    seen = Counter()
    kept = Counter()
    total = Counter()
    for ann in coco['annotations']:  # annotation order = instance order
        if ann['iscrowd']:
            continue
        seen[ann['image_id']] += 1
        total[ann['category_id']] += 1
        kept[ann['category_id']] += seen[ann['image_id']] > num_dropped
    rec_thrs = np.linspace(0, 1, 101)
    aps = [(rec_thrs <= kept[c] / total[c]).sum() / 101 if kept[c] else 0.
           for c in total]
    return 100 * float(np.mean(aps))


def test_ap_drop_end_to_end(cityscapes_like_root, tmp_path):
    """Oracle model through Runner.test on clear and foggy val: the foggy
    run reads the foggy images; AP/mIoU 100 on clear, and on foggy the
    drop of the instances the oracle leaves out there (the first one of
    each image at beta 0.01, the first two at 0.02): a known AP drop,
    larger for the denser fog."""
    root = cityscapes_like_root + '/'
    ann_file = root + 'annotations/instancesonly_filtered_gtFine_val.json'
    with open(ann_file) as f:
        coco = json.load(f)
    cfg = Config.fromfile(CFG)
    cfg.default_scope = 'mmdet'
    cfg.model = dict(type='_CBNetTestOracle',
                     data_preprocessor=dict(type='DetDataPreprocessor'))
    cfg.test_cfg = dict(type='TestLoop')
    ds = cfg.test_dataloader.dataset
    ds.data_root = root
    ds.pipeline = [p for p in ds.pipeline if p['type'] != 'Resize']
    cfg.test_dataloader.update(num_workers=0, persistent_workers=False)
    for m in cfg.test_evaluator:
        m['ann_file'] = ann_file
        if m['type'] == 'CBNetInstanceMIoUMetric':
            m['ignore_crowd'] = True  # the oracle predicts no crowds
    cfg.log_level = 'WARNING'
    ckpt = str(tmp_path / 'oracle.pth')
    torch.save({'state_dict': {'dummy': torch.zeros(1)}}, ckpt)
    cfg_file = str(tmp_path / 'oracle_cfg.py')
    cfg.dump(cfg_file)
    spec = importlib.util.spec_from_file_location(
        'ap_drop_tool', osp.join(ROOT, 'tools', 'analysis_tools',
                                 'ap_drop.py'))
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    SEEN.clear()
    out = tmp_path / 'out'
    table = tool.main([cfg_file, ckpt, '--betas', '0.01', '0.02',
                       '--out-dir', str(out)])
    assert len(SEEN) == 9
    assert all('/leftImg8bit/val/' in p for p in SEEN[:3])
    assert all(p.endswith('_foggy_beta_0.01.png') for p in SEEN[3:6])
    assert all(p.endswith('_foggy_beta_0.02.png') for p in SEEN[6:])
    assert [r['condition'] for r in table['rows']] == [
        'clear', 'foggy beta=0.01', 'foggy beta=0.02'
    ]
    clear, fog1, fog2 = table['rows']
    assert clear['mask AP'] == clear['box AP'] == clear['mIoU'] == 100.0
    assert clear['mask AP drop'] == clear['mIoU drop'] == 0.0
    for row, beta in ((fog1, '0.01'), (fog2, '0.02')):
        ap = expected_ap(coco, DROPPED[beta])
        assert 0 < ap < 100
        for col in ('box AP', 'mask AP'):
            assert row[col] == pytest.approx(ap, abs=1e-6), (beta, col)
            assert row[f'{col} drop'] == pytest.approx(100 - ap, abs=1e-6)
        assert row['mIoU drop'] == pytest.approx(100 - row['mIoU'])
    # denser fog, more instances missed: larger drops (a swapped row or a
    # sign error fails here)
    assert 0 < fog1['mIoU drop'] < fog2['mIoU drop']
    assert 0 < fog1['mask AP drop'] < fog2['mask AP drop']
    with open(out / 'ap_drop.json') as f:
        assert json.load(f)['rows'] == table['rows']
    assert (out / 'ap_drop.md').read_text().startswith('| condition |')
