import importlib.util
import json
import os.path as osp
from collections import Counter

import numpy as np
import pytest
from mmengine.config import Config

from cbnet_lab.ap_drop import drop_table, to_markdown
from cbnet_lab.config_edits import condition_cfg

ROOT = osp.join(osp.dirname(__file__), '..', '..')
CFG = osp.join(ROOT, 'configs', '_base_', 'datasets',
               'cityscapes_instance.py')
#: Per fog density, how many instances of each image (the first ones, in
#: annotation order) the oracle leaves out on the foggy images: a known AP
#: drop, larger for the denser fog.
DROPPED = {'0.01': 1, '0.02': 2}


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
    # a VOC real-fog folder of the user's own name: the error says how it
    # is tested
    cfg.test_dataloader.dataset.type = 'CBNetVOCFogDataset'
    cfg.data_root = 'data/my_fog/'
    with pytest.raises(ValueError, match=r"'data/my_fog/'.*test_conditions"
                       r".*--real-fog FOLDER"):
        condition_cfg(cfg, None)


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


def test_a_single_condition_has_no_drop():
    """A real-fog set alone has no reference: no "drop 0.0" columns."""
    table = drop_table({'real fog': {'coco/bbox_mAP': 0.5}})
    assert table['columns'] == ['box AP', 'mask AP', 'mask AP50', 'mIoU']
    assert table['rows'] == [{'condition': 'real fog', 'box AP': 50.0,
                              'mask AP': None, 'mask AP50': None,
                              'mIoU': None}]
    assert 'drop' not in to_markdown(table)


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


def test_ap_drop_end_to_end(make_oracle, tmp_path):
    """Oracle model through Runner.test on clear and foggy val: the foggy
    run reads the foggy images; AP/mIoU 100 on clear, and on foggy the
    drop of the instances the oracle leaves out there (the first one of
    each image at beta 0.01, the first two at 0.02): a known AP drop,
    larger for the denser fog."""
    oracle = make_oracle(DROPPED)
    ann_file = Config.fromfile(
        oracle['cfg_file']).test_evaluator[0]['ann_file']
    with open(ann_file) as f:
        coco = json.load(f)
    spec = importlib.util.spec_from_file_location(
        'ap_drop_tool', osp.join(ROOT, 'tools', 'analysis_tools',
                                 'ap_drop.py'))
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    out = tmp_path / 'out'
    table = tool.main([oracle['cfg_file'], oracle['ckpt'], '--betas', '0.01',
                       '0.02', '--out-dir', str(out)])
    SEEN = [path for path, _ in oracle['seen']]
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
        # MMDet's CocoMetric rounds to 3 decimals (0.1 percent)
        for col in ('box AP', 'mask AP'):
            assert row[col] == pytest.approx(ap, abs=0.051), (beta, col)
            assert row[f'{col} drop'] == pytest.approx(100 - ap, abs=0.051)
        assert row['mIoU drop'] == pytest.approx(100 - row['mIoU'])
    # denser fog, more instances missed: larger drops (a swapped row or a
    # sign error fails here)
    assert 0 < fog1['mIoU drop'] < fog2['mIoU drop']
    assert 0 < fog1['mask AP drop'] < fog2['mask AP drop']
    with open(out / 'ap_drop.json') as f:
        assert json.load(f)['rows'] == table['rows']
    assert (out / 'ap_drop.md').read_text().startswith('| condition |')
