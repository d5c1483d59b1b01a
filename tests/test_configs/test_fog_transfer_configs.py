"""The fog_transfer configs, on ImageNet trunks (fog_transfer) and from
a COCO start (fog_transfer_coco): every row is its clear row plus one
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
    glob.glob(osp.join(ROOT, 'configs', '*', 'fog_transfer', '*.py')) +
    glob.glob(osp.join(ROOT, 'projects', 'peer_dehaze', 'configs', '*',
                       'fog_transfer', '*.py')))
#: (set, row name, config) of the two transfer sets from COCO street
SET = [(name, row, path) for name in ('fog_transfer', 'fog_transfer_coco')
       for row, path in rc.resolve_recipes(name)]
GENERATED = rc.resolve_recipes('fog_generated_to_real')
#: the second test set of the sets: DAWN's val split
TRANSFER = dict(condition='real fog', data_root='data/dawn_fog/',
                split='val', val_fraction=0.3, split_seed=0)
STREET = dict(rc.resolve_recipes('coco_street'))
COCO_STREET = dict(rc.resolve_recipes('coco_street_coco_trunk'))
#: trunk and heads: the row each family starts from, and whether its
#: clear row trains on that row's data too (the two-stage ones: the
#: coco_street rows; YOLOX-Nano: the DAWN recipe's model, optimiser and
#: hooks, on the street photos)
FAMILIES = {
    'Cascade Mask R-CNN, COCO trunk':
    (COCO_STREET['Cascade Mask R-CNN, COCO trunk'], True),
    'YOLOX-Nano COCO':
    (dict(rc.resolve_recipes('realfog_coco'))['YOLOX-Nano COCO, fine-tuned'],
     False),
    'Cascade Mask R-CNN': (STREET['Cascade Mask R-CNN'], True),
    'CBNet-PT': (STREET['CBNet-PT'], True),
}


def family_of(name):
    """The longest family name the row names (the COCO-trunk cascade's
    rows name the ImageNet cascade's too)."""
    return max((f for f in FAMILIES if f in name), key=len)


def load(path):
    return read_config(path)


@pytest.fixture(autouse=True)
def empty_cache(tmp_path, monkeypatch):
    """No weights file anywhere the configs look."""
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'empty'))


def test_every_config_is_in_a_set():
    assert sorted([osp.normpath(p) for _, _, p in SET] +
                  [osp.normpath(p) for _, p in GENERATED]) == SHIPPED
    assert len(SET) == 19 and len(GENERATED) == 4
    # the sets' runs are also tested on DAWN's val split (the same 65
    # photos as the realfog_pretrained set)
    for name in ('fog_transfer', 'fog_transfer_coco',
                 'fog_generated_to_real'):
        assert rc.SETS[name].transfer_test == TRANSFER


@pytest.mark.parametrize('name,path', GENERATED[1::2],
                         ids=[n for n, _ in GENERATED[1::2]])
def test_generated_fog_row_is_its_clear_row_on_depth_fog(name, path):
    """Item 3: the fog_transfer rows' model on the generated scenes; the
    fog row trains on their depth-rendered fog, tests as the clear row."""
    clear_path = dict(GENERATED)[name.replace('generated fog',
                                              'generated clear')]
    clear, cfg = load(clear_path), load(path)
    family = family_of(name)
    assert clear.model == load(FAMILIES[family][0]).model
    assert clear.train_dataloader.dataset.dataset.type == \
        'CBNetCityscapesDataset'
    fog = cfg.train_dataloader.dataset.dataset
    assert (fog.type, fog.beta) == ('CBNetFoggyCityscapesDataset', 0.02)
    fog.type = 'CBNetCityscapesDataset'
    fog.pop('beta')
    assert cfg.train_dataloader == clear.train_dataloader
    assert cfg.model == clear.model
    assert cfg.test_dataloader == clear.test_dataloader


@pytest.mark.parametrize('set_name,name,path', SET,
                         ids=[n for _, n, _ in SET])
def test_row_is_its_clear_row_plus_one_change(set_name, name, path):
    family = family_of(name)
    rows = {n: p for s, n, p in SET if s == set_name}
    clear = load(rows[f'{family}, clear'])
    start, same_data = FAMILIES[family]
    street = load(start)
    cfg = load(path)
    # the clear row is the family's recipe, also tested on DAWN's val
    assert clear.model == street.model
    if same_data:
        assert clear.train_dataloader == street.train_dataloader
        assert clear.test_dataloader == street.test_dataloader
    else:
        assert clear.optim_wrapper == street.optim_wrapper
        assert clear.custom_hooks == street.custom_hooks
        assert clear.load_from == street.load_from
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
        assert rc.SETS[set_name].recipe(name).weights_of == \
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


@pytest.mark.parametrize('name,path', [(n, p) for _, n, p in SET] +
                         GENERATED,
                         ids=[n for _, n, _ in SET] +
                         [n for n, _ in GENERATED])
def test_builds_without_weights_and_tests_on_real_fog(name, path,
                                                      tmp_path):
    cfg = load(path)
    init_default_scope('mmdet')
    model = MODELS.build(cfg.model)  # no weights file read at build time
    model.eval()
    with torch.no_grad():
        # YOLOX's three levels; the two-stage models' FPN five
        assert len(model.extract_feat(torch.zeros(1, 3, 128, 192))) == \
            (3 if 'YOLOX' in name else 5)
    # the second test set: DAWN's val split through the recipe's own test
    # pipeline, boxes only
    fog = transfer_cfg(cfg, TRANSFER, str(tmp_path))
    dataset = fog.test_dataloader.dataset
    assert (dataset.type, dataset.data_root, dataset.split,
            dataset.val_fraction, dataset.split_seed) == \
        ('CBNetVOCFogDataset', str(tmp_path), 'val', 0.3, 0)
    assert fog.test_evaluator == [dict(type='CocoMetric', metric='bbox')]
    assert dataset.pipeline[2] == cfg.test_dataloader.dataset.pipeline[2]


def test_yolox_clear_row_trains_on_the_street_boxes_as_long():
    """YOLOX-Nano's clear row: the street photos with a street object,
    boxes only, batches of 4 for the coco_street budget's 36 epochs, its
    schedule and checkpoint made for them (not the DAWN recipe's 12); its
    rows run at that batch and half the set's iterations (the same images
    seen)."""
    rows = {n: p for s, n, p in SET if s == 'fog_transfer_coco'}
    cfg = load(rows['YOLOX-Nano COCO, clear'])
    data = cfg.train_dataloader
    assert data.batch_size == 4
    assert data.dataset.type == 'CBNetCityscapesDataset'
    assert data.dataset.filter_cfg.filter_empty_gt
    for loader in (data, cfg.test_dataloader):
        loads = [t for t in loader.dataset.pipeline
                 if t['type'] == 'LoadAnnotations']
        assert [t.get('with_mask', False) for t in loads] == [False]
    assert [e.metric for e in cfg.test_evaluator] == ['bbox']
    assert cfg.train_cfg.max_epochs == 36
    assert cfg.param_scheduler[1].end == cfg.param_scheduler[1].T_max == 36
    assert cfg.default_hooks.checkpoint.interval == 36
    for name in rows:
        if 'YOLOX' in name:
            assert rc.SETS['fog_transfer_coco'].recipe(name).budget == \
                dict(batch_size=4, iters_scale=0.5)
