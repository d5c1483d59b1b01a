"""The realfog set: box-only recipes on a VOC real-fog folder, the demo's
trunk and budget, dehazers where the set says (configs/realfog, and the
dehazer + detector recipes of projects/peer_dehaze/configs/realfog)."""
import glob
import os.path as osp

import pytest

from cbnet_lab.config_edits import read_config
from cbnet_lab import recipe_comparison as rc
from cbnet_lab.sets import data_condition

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
REALFOG = osp.join(ROOT, 'configs', 'realfog')
DEHAZE_REALFOG = osp.join(ROOT, 'projects', 'peer_dehaze', 'configs',
                          'realfog')
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
RECIPES = dict(rc.resolve_recipes('realfog'))


def test_every_recipe_config_of_the_folder_is_in_the_set():
    shipped = set(glob.glob(osp.join(REALFOG, '*_voc-fog.py')) +
                  glob.glob(osp.join(DEHAZE_REALFOG, '*_voc-fog.py')))
    assert shipped == {osp.normpath(p) for p in RECIPES.values()}
    assert len(RECIPES) == 7


@pytest.mark.parametrize('name', sorted(RECIPES))
def test_recipe_is_box_only_on_the_real_fog_splits(name):
    cfg, demo = read_config(RECIPES[name]), read_config(DEMO)
    assert data_condition(cfg.data_root) == 'real fog'
    train = cfg.train_dataloader.dataset
    test = cfg.test_dataloader.dataset
    for ds, split in ((train, 'train'), (test, 'val')):
        assert ds.type == 'CBNetVOCFogDataset'
        assert ds.split == split and ds.ann_file == ''
        assert ds.data_root == cfg.data_root == 'data/dawn_fog/'
        loads = [t for t in ds.pipeline if t.type == 'LoadAnnotations']
        assert loads and not loads[0].get('with_mask', False)
    # one split for every recipe
    assert (train.split_seed, train.val_fraction) == \
        (test.split_seed, test.val_fraction)
    assert test.test_mode and 'instances' in test.pipeline[-1].meta_keys
    assert [e.type for e in cfg.test_evaluator] == ['CocoMetric']
    assert cfg.test_evaluator[0].metric == 'bbox'
    assert 'ann_file' not in cfg.test_evaluator[0]
    model = cfg.model
    if model.type == 'YOLOX':
        assert model.bbox_head.num_classes == 8
    else:  # the demo's trunk, no mask head
        assert model.backbone == demo.model.backbone
        assert model.roi_head.get('mask_head') is None
        assert model.roi_head.get('mask_roi_extractor') is None
        assert not model.data_preprocessor.pad_mask
    for key in ('optim_wrapper', 'randomness'):
        assert cfg.get(key) == demo.get(key), key
    pre = model.data_preprocessor
    if name.startswith('DCP'):
        assert pre.type == 'CBNetDehazeDataPreprocessor'
        assert pre.dehaze.type == 'CBNetDarkChannelPrior'
        assert pre.dehaze_checkpoint is None
    elif name.startswith('dehazer'):
        assert pre.type == 'CBNetDehazeDataPreprocessor'
        assert pre.dehaze.type == 'CBNetAttentionDehazer'
        assert not pre.train_dehazer
    else:
        assert pre.type == 'DetDataPreprocessor'
