"""The COCO-pretrained YOLOX-Nano configs (configs/yolox_coco and the peer
baseline's dehaze-then-detect ones): every one is a row of the
realfog_coco set, builds with no weights file present, and differs from
the fine-tuned recipe by what its name says only."""
import glob
import os.path as osp

import pytest
from mmdet.registry import MODELS
from mmengine.registry import init_default_scope

from cbnet_lab import recipe_comparison as rc
from cbnet_lab.config_edits import read_config
from cbnet_tools import pretrained as pt

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
FOLDERS = (osp.join(ROOT, 'configs', 'yolox_coco'),
           osp.join(ROOT, 'projects', 'peer_dehaze', 'configs', 'yolox_coco'))
RECIPES = dict(rc.resolve_recipes('realfog_coco'))
FT = RECIPES['YOLOX-Nano COCO, fine-tuned']
COCO_FILE = 'yolox-nano_coco_megvii-0.1.1rc0.pth'
STREET_FILE = 'yolox-nano_coco_megvii-0.1.1rc0_to-cityscapes-8.pth'


def hook_types(cfg):
    return [h['type'] for h in cfg.get('custom_hooks', [])]


def test_every_config_of_the_folders_is_a_row():
    shipped = {osp.normpath(p) for folder in FOLDERS
               for p in glob.glob(osp.join(folder, '*.py'))}
    assert shipped == {osp.normpath(p) for p in RECIPES.values()}


@pytest.mark.parametrize('name', sorted(RECIPES))
def test_builds_without_weights_on_the_shared_split(name, tmp_path,
                                                    monkeypatch):
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'none'))
    cfg = read_config(RECIPES[name])
    init_default_scope('mmdet')
    model = MODELS.build(cfg.model)
    assert type(model).__name__ == 'YOLOX'
    assert cfg.load_from.startswith(str(tmp_path / 'none'))
    zero_shot = 'zero-shot' in name
    assert osp.basename(cfg.load_from) == \
        (COCO_FILE if zero_shot or 'fresh classifier' in name
         else STREET_FILE)
    # a COCO head of 80 classes zero-shot, the 8 street classes otherwise
    assert cfg.model.bbox_head.num_classes == (80 if zero_shot else 8)
    test = cfg.test_dataloader.dataset
    assert test.type == 'CBNetVOCFogDataset' and test.split == 'val'
    assert (test.split_seed, test.val_fraction) == (0, 0.3)
    # YOLOX takes raw 0-255 BGR, padded with its grey
    pre = cfg.model.data_preprocessor
    assert pre.pad_value == 114 and pre.get('batch_augments') is None
    assert pre.type == ('CBNetDehazeDataPreprocessor'
                        if name.startswith(('DCP', 'dehazer'))
                        else 'DetDataPreprocessor')
    if name.startswith('dehazer'):  # the learned dehazer, frozen
        assert pre.dehaze.type == 'CBNetAttentionDehazer'
        assert pre.dehaze_checkpoint.endswith('iter_200.pth')
        assert not pre.train_dehazer
    if zero_shot:
        assert cfg.train_dataloader is None and cfg.train_cfg is None
        assert cfg.optim_wrapper is None and hook_types(cfg) == []
        evaluator = cfg.test_evaluator
        assert evaluator.type == 'CBNetClassMapMetric'
        assert evaluator.source_classes == 'coco'
        assert evaluator.metric.type == 'CocoMetric'
        return
    assert cfg.train_dataloader.batch_size == 4
    assert cfg.train_cfg.max_epochs == 12
    assert cfg.optim_wrapper.optimizer.type == 'AdamW'
    # the batch norms stay frozen (folded weights) unless the row says
    hooks = hook_types(cfg)
    assert ('CBNetNormEvalHook' in hooks) == ('batch norms trained'
                                              not in name)
    assert ('EMAHook' in hooks) == ('no EMA' not in name)


def test_variants_change_only_what_their_names_say():
    base = read_config(FT)
    for name, path in RECIPES.items():
        cfg = read_config(path)
        train = cfg.get('train_dataloader')
        if train is None:
            continue
        types = [t['type'] for t in (train.dataset.get('pipeline') or [])]
        if 'mosaic' in name:
            assert train.dataset.type == 'MultiImageMixDataset'
            assert [t['type'] for t in train.dataset.pipeline][:2] == [
                'Mosaic', 'RandomAffine']
            assert train.dataset.dataset.type == 'CBNetVOCFogDataset'
            continue
        assert ('CBNetAddFog' in types) == ('fog aug' in name)
        resize = [t for t in train.dataset.pipeline
                  if t['type'] == 'Resize'][0]
        base_resize = [t for t in base.train_dataloader.dataset.pipeline
                       if t['type'] == 'Resize'][0]
        if '416 px' in name:
            assert tuple(resize['scale']) == (416, 312)
            assert rc.SETS['realfog_coco'].recipe(name).keep_img_scale
        else:
            assert resize == base_resize
        assert cfg.optim_wrapper == base.optim_wrapper
        assert cfg.param_scheduler == base.param_scheduler


def test_training_without_weights_names_the_fetch_command(tmp_path,
                                                          monkeypatch):
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'none'))
    for name in ('YOLOX-Nano COCO, fine-tuned',
                 'YOLOX-Nano COCO, fine-tuned, fresh classifier',
                 'YOLOX-Nano COCO, zero-shot'):
        with pytest.raises(FileNotFoundError,
                           match='fetch_pretrained.py yolox_nano'):
            pt.require_pretrained(read_config(RECIPES[name]))
    # a resumed run loads its own checkpoint, not the pretrained file
    cfg = read_config(FT)
    cfg.resume = True
    pt.require_pretrained(cfg)
