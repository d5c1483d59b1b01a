"""The two-stage recipes on YOLOX-Nano's COCO trunk (configs/coco_trunk):
every config is a row of a set, builds with no weights file present,
feeds the trunk YOLOX's input (raw 0-255 BGR), keeps its batch norms in
eval mode, loads the trunk (and, where named, the PAFPN) from the
converted COCO file, and each fine-tuning variant differs from its
recipe by what its name says only."""
import glob
import os.path as osp

import pytest
import torch
from mmdet.registry import MODELS
from mmengine.registry import init_default_scope

from cbnet_lab import recipe_comparison as rc
from cbnet_lab.config_edits import read_config
from cbnet_tools import pretrained as pt
from cbnet_tools.synthetic.yolox_checkpoints import tiny_yolox_nano

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
FOLDER = osp.join(ROOT, 'configs', 'coco_trunk')
FOG = dict(rc.resolve_recipes('realfog_coco_trunk'))
STREET = dict(rc.resolve_recipes('coco_street_coco_trunk'))
#: the stock mask recipe with one part of CBNet each (configs/coco_trunk/
#: parts; which part: tests/test_configs/test_coco_trunk_parts_configs.py)
PARTS = dict(rc.resolve_recipes('coco_street_coco_trunk_parts'))
#: the configs of configs/coco_trunk/fog_transfer (their own checks:
#: tests/test_configs/test_fog_transfer_configs.py)
TRANSFER = {n: p for n, p in rc.resolve_recipes('fog_transfer_coco')
            if osp.normpath(p).startswith(osp.join(FOLDER, 'fog_transfer'))}
STOCK = FOG['Cascade R-CNN, COCO trunk']
COCO_FILE = 'yolox-nano_coco_megvii-0.1.1rc0.pth'


def build(path):
    cfg = read_config(path)
    init_default_scope('mmdet')
    return cfg, MODELS.build(cfg.model)


def test_every_config_of_the_folder_is_a_row():
    shipped = {osp.normpath(p) for p in
               glob.glob(osp.join(FOLDER, '**', '*.py'), recursive=True)
               if '_base_' not in p}
    rows = {osp.normpath(p) for p in list(FOG.values()) +
            list(STREET.values()) + list(PARTS.values()) +
            list(TRANSFER.values())}
    assert shipped == rows


@pytest.mark.parametrize('name,path',
                         sorted({**FOG, **STREET, **PARTS}.items()))
def test_builds_without_weights_with_the_trunks_input(name, path, tmp_path,
                                                      monkeypatch):
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'none'))
    cfg, model = build(path)
    trunk = cfg.model.backbone
    assert trunk.type == 'CSPDarknet' and trunk.use_depthwise
    assert (trunk.deepen_factor, trunk.widen_factor) == (0.33, 0.25)
    assert trunk.norm_eval
    assert trunk.init_cfg.checkpoint == str(tmp_path / 'none' / COCO_FILE)
    assert trunk.init_cfg.prefix == 'backbone.'
    # YOLOX's input: raw 0-255 BGR
    pre = cfg.model.data_preprocessor
    assert (pre.mean, pre.std, pre.bgr_to_rgb) == \
        ([0.0] * 3, [1.0] * 3, False)
    masks = path in STREET.values() or path in PARTS.values()
    assert (cfg.model.roi_head.get('mask_head') is not None) == masks
    test = cfg.test_dataloader.dataset
    if masks:
        assert test.type == 'CBNetCityscapesDataset'  # COCO files
    else:
        assert test.type == 'CBNetVOCFogDataset' and test.split == 'val'
    with pytest.raises(FileNotFoundError,
                       match='fetch_pretrained.py yolox_nano'):
        pt.require_pretrained(cfg)
    assert model.with_rpn and model.with_roi_head


def test_variants_change_only_what_their_names_say():
    base = read_config(STOCK)
    lr = read_config(FOG['Cascade R-CNN, COCO trunk, trunk lr x0.1'])
    assert lr.optim_wrapper.paramwise_cfg.custom_keys.backbone.lr_mult == \
        0.1
    assert base.optim_wrapper.paramwise_cfg.custom_keys.backbone.lr_mult \
        == 1.0
    lr.optim_wrapper.paramwise_cfg.custom_keys.backbone.lr_mult = 1.0
    assert lr.optim_wrapper == base.optim_wrapper and lr.model == base.model
    stem = read_config(FOG['Cascade R-CNN, COCO trunk, stem trained'])
    # the stem and first stage frozen by default, trained in the variant
    assert (base.model.backbone.frozen_stages,
            stem.model.backbone.frozen_stages) == (1, -1)
    stem.model.backbone.frozen_stages = 1
    assert stem.model == base.model
    # the warm-up row is the stock config with its own budget
    row = rc.SETS['realfog_coco_trunk'].recipe(
        'Cascade R-CNN, COCO trunk, warm-up 200')
    assert osp.join(ROOT, 'configs', row.config) == STOCK
    assert row.budget == dict(warmup_iters=200)


def test_the_trunk_and_the_pafpn_load_the_coco_weights(tmp_path,
                                                       monkeypatch):
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'weights'))
    _, _, coco = tiny_yolox_nano()
    for path, neck in ((STOCK, False),
                       (FOG['Cascade R-CNN, COCO trunk + PAFPN'], True)):
        torch.manual_seed(0)
        _, model = build(path)
        model.init_weights()
        state = model.state_dict()
        trunk = [k for k in coco if k.startswith('backbone.')]
        assert trunk and all(torch.equal(state[k], coco[k]) for k in trunk)
        pafpn = [k for k in coco if k.startswith('neck.')]
        loaded = [torch.equal(state['neck.0.' + k[5:]], coco[k])
                  for k in pafpn if 'neck.0.' + k[5:] in state]
        assert (len(loaded) == len(pafpn) and all(loaded)) == neck
        # a training step keeps the trunk's batch-norm statistics
        model.train()
        assert not model.backbone.stem.conv.bn.training


def test_pafpn_recipe_predicts_on_its_four_levels(tmp_path, monkeypatch):
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'none'))
    cfg, model = build(FOG['Cascade R-CNN, COCO trunk + PAFPN'])
    model.eval()
    with torch.no_grad():
        feats = model.extract_feat(torch.rand(1, 3, 96, 160) * 255)
    assert [f.shape[-2:] for f in feats] == [
        (12, 20), (6, 10), (3, 5), (2, 3)]
    assert cfg.model.rpn_head.anchor_generator.strides == [8, 16, 32, 64]
    assert cfg.model.roi_head.bbox_roi_extractor.featmap_strides == \
        [8, 16, 32]
