"""End to end: the demo model learns on the generated data.

Trains the demo config (MiT-B0 CBNet, from scratch) for a few epochs on a
small seeded Cityscapes-like set and checks that its segm AP50 on the val
split is clearly above the same model's untrained AP50. The figures are
printed (pytest -s) and written to ``work_dirs/e2e_learning.json`` for the
docs/get_started.md.
"""
import json
import os
import os.path as osp
import tempfile

import pytest
from mmengine.config import Config
from mmengine.runner import Runner

import cbnet_mmdet  # noqa: F401
from cbnet_tools.cityscapes_to_coco import convert
from cbnet_tools.synthetic import generate_cityscapes_like

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
#: the learning check's budget: data size and epochs
NUM_TRAIN, NUM_VAL, EPOCHS = 32, 8, 12
#: The check's scenes: objects from 16 px up, half the default count. It
#: tests that the pipeline learns, not how hard the data is: on the default
#: scenes (half the objects under 8x8 px at 128x256) the fixed recipe
#: reaches mask AP50 0.015 vs 0.000 untrained in this budget (2026-11-23),
#: too close to zero for a margin that a broken pipeline cannot reach.
SCENE = dict(min_height_px=16.0, density=0.5)


def _cfg(data_root, work_dir, epochs):
    cfg = Config.fromfile(DEMO)
    cfg.work_dir = work_dir
    # MMEngine keeps visualisers by name for the whole process: a private
    # name, so no later test's Runner reuses one that writes into this
    # test's (deleted) temporary folder
    cfg.visualizer.name = f'cbnet_e2e_{osp.basename(work_dir)}'
    cfg.experiment_name = f'cbnet_e2e_{osp.basename(work_dir)}'
    cfg.train_cfg.max_epochs = epochs
    cfg.train_cfg.val_interval = max(epochs, 1)
    cfg.param_scheduler[1].end = max(epochs, 1)
    cfg.default_hooks.checkpoint = dict(type='CheckpointHook', interval=-1)
    cfg.default_hooks.logger.interval = 5
    ann = osp.join(data_root, 'annotations',
                   'instancesonly_filtered_gtFine_val.json')
    cfg.train_dataloader.dataset.dataset.data_root = data_root
    for loader in (cfg.val_dataloader, cfg.test_dataloader):
        loader.dataset.data_root = data_root
    for evaluators in (cfg.val_evaluator, cfg.test_evaluator):
        for ev in evaluators:
            ev.ann_file = ann
    cfg.randomness = dict(seed=0)
    return cfg


@pytest.mark.slow  # trains from scratch for a few minutes on 2 cores
def test_demo_model_learns():
    with tempfile.TemporaryDirectory(prefix='cbnet_e2e_') as tmp:
        data_root = osp.join(tmp, 'cityscapes_like')
        generate_cityscapes_like(
            data_root, num_train=NUM_TRAIN, num_val=NUM_VAL,
            img_size=(128, 256), seed=1, **SCENE)
        convert(data_root)

        untrained = Runner.from_cfg(
            _cfg(data_root, osp.join(tmp, 'untrained'), 0)).test()
        runner = Runner.from_cfg(
            _cfg(data_root, osp.join(tmp, 'trained'), EPOCHS))
        runner.train()
        trained = runner.test()

    figures = {
        'data': f'{NUM_TRAIN} train / {NUM_VAL} val generated 128x256, '
                f'seed 1, {SCENE}',
        'epochs': EPOCHS,
        'untrained': {k: untrained[k] for k in
                      ('coco/segm_mAP_50', 'coco/bbox_mAP_50')},
        'trained': {k: trained[k] for k in
                    ('coco/segm_mAP_50', 'coco/bbox_mAP_50',
                     'cityscapes/mIoU')},
    }
    print(json.dumps(figures, indent=1))
    os.makedirs(osp.join(ROOT, 'work_dirs'), exist_ok=True)
    with open(osp.join(ROOT, 'work_dirs', 'e2e_learning.json'), 'w') as f:
        json.dump(figures, f, indent=1)
    # Measured 2026-11-23 on these scenes: mask AP50 0.038 and box AP50
    # 0.046 trained vs 0.000 untrained (the fixed recipe of the accuracy
    # issue learns more slowly from scratch than the old one's 0.13 on the
    # old flat scenes). A pipeline that does not learn stays at 0.000: the
    # margin is half the measured gain, on both.
    for key in ('coco/segm_mAP_50', 'coco/bbox_mAP_50'):
        before, after = untrained[key], trained[key]
        assert after >= before + 0.02 and after >= 2 * before, figures
