import importlib.util
import json
import os.path as osp

import pytest
from mmengine.config import Config

from cbnet_mmdet.evaluation.ap_drop import (condition_cfg, drop_table,
                                            to_markdown)

ROOT = osp.join(osp.dirname(__file__), '..', '..')
CFG = osp.join(ROOT, 'configs', '_base_', 'datasets',
               'cityscapes_instance.py')


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


def test_ap_drop_end_to_end(oracle, tmp_path):
    """Oracle model through Runner.test on clear and foggy val: the foggy
    run reads the foggy images; AP/mIoU 100 on both, drop 0."""
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
    for row in table['rows']:
        assert row['mask AP'] == row['box AP'] == row['mIoU'] == 100.0
        assert row['mask AP drop'] == 0.0
    with open(out / 'ap_drop.json') as f:
        assert json.load(f)['rows'] == table['rows']
    assert (out / 'ap_drop.md').read_text().startswith('| condition |')
