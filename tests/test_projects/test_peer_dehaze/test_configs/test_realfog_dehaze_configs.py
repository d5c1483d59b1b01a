"""The peer baseline's dehazer of the realfog set
(projects/peer_dehaze/configs/realfog): trained like the project's demo
dehazer, where its detectors load it."""
import os.path as osp

from mmengine.config import Config

from cbnet_lab import recipe_comparison as rc

ROOT = osp.abspath(osp.join(osp.dirname(__file__), *['..'] * 4))
CONFIGS = osp.join(ROOT, 'projects', 'peer_dehaze', 'configs')
RECIPES = dict(rc.resolve_recipes('realfog'))
DEHAZER = osp.join(CONFIGS, 'realfog',
                   'dehazer_attention_1xb4-200it_cityscapes-like.py')


def test_learned_dehazer_is_where_its_config_writes_it():
    """The realfog dehazer config trains the demo dehazer on the generated
    pairs with 64x64 crops for 200 iterations; train_dehazer.py writes
    work_dirs/dehaze/<config name>/iter_<max_iters>.pth, which the
    detectors load."""
    cfg = Config.fromfile(DEHAZER)
    demo = Config.fromfile(osp.join(
        CONFIGS, 'dehazer_attention_1xb4-600it_cityscapes-like.py'))
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
