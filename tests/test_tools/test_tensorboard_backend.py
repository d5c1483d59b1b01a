"""TensorBoard as the visualisation backend (docs/visualization.md).

The demo model trains two iterations with the documented
``visualizer.vis_backends``; the losses read back from TensorBoard's event
file equal those MMEngine's JSON backend wrote in the same run.
"""
import glob
import json
import os.path as osp

import pytest
from mmengine.config import Config
from mmengine.runner import Runner
from tensorboard.backend.event_processing.event_accumulator import \
    EventAccumulator

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
#: The snippet of docs/visualization.md.
TENSORBOARD = dict(visualizer=dict(vis_backends=[
    dict(type='LocalVisBackend'),
    dict(type='TensorboardVisBackend'),
]))


@pytest.mark.slow  # builds and trains the demo model 2 iterations (~20 s)
def test_tensorboard_receives_the_training_scalars(cityscapes_like_root,
                                                   tmp_path):
    cfg = Config.fromfile(DEMO)
    cfg.merge_from_dict(TENSORBOARD)
    # MMEngine keeps visualisers by name for the whole process: a private
    # name, so this Runner does not reuse an earlier test's (which writes
    # into that test's folder)
    cfg.visualizer.name = f'cbnet_tensorboard_{tmp_path.name}'
    cfg.experiment_name = f'cbnet_tensorboard_{tmp_path.name}'
    data = cfg.train_dataloader.dataset.dataset
    data.data_root = cityscapes_like_root + '/'
    for t in data.pipeline:
        if t['type'] == 'Resize':
            t['scale'] = (128, 64)  # half size, for speed
    cfg.train_dataloader.update(batch_size=2, num_workers=0,
                                persistent_workers=False)
    cfg.model.train_cfg.rpn_proposal.update(nms_pre=200, max_per_img=50)
    for rcnn in cfg.model.train_cfg.rcnn:
        rcnn.sampler.num = 32
    cfg.merge_from_dict(
        dict(train_cfg=dict(max_epochs=1, val_interval=100),
             default_hooks=dict(logger=dict(interval=1),
                                checkpoint=dict(interval=100)),
             randomness=dict(seed=0), log_level='WARNING'))
    for key in ('val_dataloader', 'val_evaluator', 'val_cfg',
                'test_dataloader', 'test_evaluator', 'test_cfg'):
        cfg[key] = None
    cfg.work_dir = str(tmp_path / 'work')
    Runner.from_cfg(cfg).train()

    (vis_dir, ) = glob.glob(osp.join(cfg.work_dir, '*', 'vis_data'))
    events = glob.glob(osp.join(vis_dir, 'events.out.tfevents.*'))
    assert len(events) == 1
    acc = EventAccumulator(events[0])
    acc.Reload()
    tags = acc.Tags()['scalars']
    assert {'loss', 'lr', 's2.loss_mask'} <= set(tags), tags
    board = {e.step: e.value for e in acc.Scalars('loss')}
    with open(osp.join(vis_dir, 'scalars.json')) as f:
        local = {
            r['step']: r['loss']
            for r in map(json.loads, f) if 'loss' in r
        }
    assert sorted(board) == sorted(local) == [1, 2]
    for step, value in local.items():
        assert board[step] == pytest.approx(value, rel=1e-6)
