"""The fog_transfer configs: every row is its clear row plus one
stated change (synthetic fog in the training pipeline, CBNet-DD's model
and twin pipeline, the dark channel prior or the learned dehazer at test
time on the clear row's weights), tested also on DAWN's val split; each
builds with no weights file."""
import glob
import os.path as osp

import pytest
import torch
from mmdet.registry import MODELS
from mmengine.registry import init_default_scope

from cbnet_lab import recipe_comparison as rc
from cbnet_lab.config_edits import read_config, transfer_cfg
from cbnet_tools import pretrained as pt

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
SHIPPED = sorted(
    glob.glob(osp.join(ROOT, 'configs', 'pretrained', 'fog_transfer',
                       '*.py')) +
    glob.glob(osp.join(ROOT, 'projects', 'peer_dehaze', 'configs',
                       'pretrained', 'fog_transfer', '*.py')))
SET = rc.resolve_recipes('fog_transfer')
GENERATED = rc.resolve_recipes('fog_generated_to_real')
#: the second test set of both sets: DAWN's val split
TRANSFER = dict(condition='real fog', data_root='data/dawn_fog/',
                split='val', val_fraction=0.3, split_seed=0)
STREET = dict(rc.resolve_recipes('coco_street'))
#: trunk and heads: the coco_street row each family starts from
FAMILIES = {'Cascade Mask R-CNN': STREET['Cascade Mask R-CNN'],
            'CBNet-PT': STREET['CBNet-PT']}


def load(path):
    return read_config(path)


@pytest.fixture(autouse=True)
def empty_cache(tmp_path, monkeypatch):
    """No weights file anywhere the configs look."""
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'empty'))


def test_every_config_is_in_a_set():
    assert sorted(osp.normpath(p) for _, p in SET + GENERATED) == SHIPPED
    assert len(SET) == 10 and len(GENERATED) == 4
    # both sets' runs are also tested on DAWN's val split (the same 65
    # photos as the realfog_pretrained set)
    for name in ('fog_transfer', 'fog_generated_to_real'):
        assert rc.SETS[name].transfer_test == TRANSFER


@pytest.mark.parametrize('name,path', GENERATED[1::2],
                         ids=[n for n, _ in GENERATED[1::2]])
def test_generated_fog_row_is_its_clear_row_on_depth_fog(name, path):
    """Item 3: the fog_transfer rows' model on the generated scenes; the
    fog row trains on their depth-rendered fog, tests as the clear row."""
    clear_path = dict(GENERATED)[name.replace('generated fog',
                                              'generated clear')]
    clear, cfg = load(clear_path), load(path)
    family = next(f for f in FAMILIES if f in name)
    assert clear.model == load(FAMILIES[family]).model
    assert clear.train_dataloader.dataset.dataset.type == \
        'CBNetCityscapesDataset'
    fog = cfg.train_dataloader.dataset.dataset
    assert (fog.type, fog.beta) == ('CBNetFoggyCityscapesDataset', 0.02)
    fog.type = 'CBNetCityscapesDataset'
    fog.pop('beta')
    assert cfg.train_dataloader == clear.train_dataloader
    assert cfg.model == clear.model
    assert cfg.test_dataloader == clear.test_dataloader


@pytest.mark.parametrize('name,path', SET, ids=[n for n, _ in SET])
def test_row_is_its_clear_row_plus_one_change(name, path):
    family = next(f for f in FAMILIES if f in name)
    clear = load(dict(SET)[f'{family}, clear'])
    street = load(FAMILIES[family])
    cfg = load(path)
    # the clear row is the coco_street recipe, also tested on DAWN's val
    assert clear.model == street.model
    assert clear.train_dataloader == street.train_dataloader
    assert clear.test_dataloader == street.test_dataloader
    assert cfg.test_dataloader == clear.test_dataloader
    steps = [t['type'] for t in cfg.train_dataloader.dataset.pipeline]
    plain = [t['type'] for t in clear.train_dataloader.dataset.pipeline]
    if name.endswith(', clear'):
        assert cfg.filename == clear.filename
    elif name.endswith('fog aug'):
        assert steps == plain[:2] + ['CBNetAddFog'] + plain[2:]
        fog = cfg.train_dataloader.dataset.pipeline[2]
        assert fog.beta == (0.005, 0.02) and fog.prob == 0.5
        assert cfg.model == clear.model
    elif name.endswith('CBNet-DD'):
        assert steps == plain[:2] + ['CBNetAddFoggyTwin'] + plain[2:]
        twin = cfg.train_dataloader.dataset.pipeline[2]
        assert twin.beta == (0.005, 0.02) and twin.get('prob', 1.0) == 1.0
        assert cfg.model.type == 'CBNetDistiller'
        assert cfg.model.detector == clear.model
        assert cfg.model.data_preprocessor == dict(
            clear.model.data_preprocessor,
            type='CBNetPairedDataPreprocessor')
        assert [h.type for h in cfg.custom_hooks] == ['CBNetTeacherEMAHook']
    else:  # a dehazer in front of the clear row's weights, test only
        assert rc.SETS['fog_transfer'].recipe(name).weights_of == \
            f'{family}, clear'
        front = cfg.model.data_preprocessor
        assert front.type == 'CBNetDehazeDataPreprocessor'
        assert not front.train_dehazer
        dehazers = load(osp.join(ROOT, 'projects', 'peer_dehaze', 'configs',
                                 'realfog', '_base_', 'dehazers.py'))
        if name.startswith('DCP + '):
            assert front.dehaze == dehazers.fog_dcp
            assert front.dehaze_checkpoint is None
        else:  # the realfog set's learned dehazer, its checkpoint
            assert name.startswith('dehazer + ')
            assert front.dehaze.type == 'CBNetAttentionDehazer'
            assert front.dehaze_checkpoint == \
                dehazers.fog_dehazer_checkpoint
        pre = {k: v for k, v in cfg.model.data_preprocessor.items()
               if k in clear.model.data_preprocessor and k != 'type'}
        assert pre == {k: v for k, v in clear.model.data_preprocessor.items()
                       if k != 'type'}
        cfg.model.data_preprocessor = clear.model.data_preprocessor
        assert cfg.model == clear.model


@pytest.mark.parametrize('name,path', SET + GENERATED,
                         ids=[n for n, _ in SET + GENERATED])
def test_builds_without_weights_and_tests_on_real_fog(name, path,
                                                      tmp_path):
    cfg = load(path)
    init_default_scope('mmdet')
    model = MODELS.build(cfg.model)  # no weights file read at build time
    model.eval()
    with torch.no_grad():
        assert len(model.extract_feat(torch.zeros(1, 3, 128, 192))) == 5
    # the second test set: DAWN's val split through the recipe's own test
    # pipeline, boxes only
    fog = transfer_cfg(cfg, TRANSFER, str(tmp_path))
    dataset = fog.test_dataloader.dataset
    assert (dataset.type, dataset.data_root, dataset.split,
            dataset.val_fraction, dataset.split_seed) == \
        ('CBNetVOCFogDataset', str(tmp_path), 'val', 0.3, 0)
    assert fog.test_evaluator == [dict(type='CocoMetric', metric='bbox')]
    assert dataset.pipeline[2] == cfg.test_dataloader.dataset.pipeline[2]
