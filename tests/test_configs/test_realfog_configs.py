"""configs/realfog: box-only recipes on a VOC real-fog folder, the demo's
trunk and budget, dehazers where the set says."""
import glob
import os.path as osp

import pytest
from mmengine.config import Config

from cbnet_lab import recipe_comparison as rc

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
REALFOG = osp.join(ROOT, 'configs', 'realfog')
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
RECIPES = dict(rc.resolve_recipes('realfog'))
DEHAZER = osp.join(REALFOG, 'dehazer_attention_1xb4-200it_cityscapes-like.py')


def test_every_recipe_config_of_the_folder_is_in_the_set():
    shipped = set(glob.glob(osp.join(REALFOG, '*_voc-fog.py')))
    assert shipped == set(RECIPES.values())
    assert len(RECIPES) == 7


@pytest.mark.parametrize('name', sorted(RECIPES))
def test_recipe_is_box_only_on_the_real_fog_splits(name):
    cfg, demo = Config.fromfile(RECIPES[name]), Config.fromfile(DEMO)
    assert cfg.test_condition == 'real fog'
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


def test_learned_dehazer_is_where_its_config_writes_it():
    """The realfog dehazer config trains the demo dehazer on the generated
    pairs with 64x64 crops for 200 iterations; train_dehazer.py writes
    work_dirs/dehaze/<config name>/iter_<max_iters>.pth, which the
    detectors load."""
    cfg = Config.fromfile(DEHAZER)
    demo = Config.fromfile(osp.join(
        ROOT, 'configs', 'dehaze',
        'dehazer_attention_1xb4-600it_cityscapes-like.py'))
    assert cfg.model == demo.model
    assert cfg.train_cfg.max_iters == 200
    assert cfg.default_hooks.checkpoint.interval == 200
    assert cfg.param_scheduler[-1].end == 200
    datasets = cfg.train_dataloader.dataset.datasets
    assert [d.beta for d in datasets] == [0.005, 0.01, 0.02]
    for d in datasets:
        assert d.type == 'CBNetPairedFoggyDataset'
        crops = [t for t in d.pipeline if t.type == 'RandomCrop']
        assert [t.crop_size for t in crops] == [(64, 64)]
    name = osp.splitext(osp.basename(DEHAZER))[0]
    for recipe in ('dehazer + Cascade R-CNN', 'dehazer + YOLOX-Tiny'):
        pre = Config.fromfile(RECIPES[recipe]).model.data_preprocessor
        assert pre.dehaze_checkpoint == \
            f'work_dirs/dehaze/{name}/iter_200.pth'
        assert pre.dehaze == demo.model.dehazer
