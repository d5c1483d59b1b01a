"""Test-only hooks: a crash, a SIGKILL, and a dump of each rank's weights;
a toy model and its config for ``tools/train.py``.

Imported by the training subprocesses through ``custom_imports`` (this
folder is put on their ``PYTHONPATH``) and by the tests themselves.
"""
import os
import os.path as osp
import signal
import uuid

import torch
from mmdet.registry import HOOKS, MODELS
from mmengine.dist import get_rank
from mmengine.hooks import Hook
from mmengine.model import BaseModel, is_model_wrapper


@HOOKS.register_module(force=True)
class CBNetTestSigkillHook(Hook):
    """Kill the process (no clean-up, no checkpoint) before an iteration.

    Args:
        at_iter (int): 0-based iteration before which to die.
    """

    priority = 'HIGHEST'

    def __init__(self, at_iter: int) -> None:
        self.at_iter = at_iter

    def before_train_iter(self, runner, batch_idx, data_batch=None):
        if runner.iter == self.at_iter:
            os.kill(os.getpid(), signal.SIGKILL)


@HOOKS.register_module(force=True)
class CBNetTestCrashHook(CBNetTestSigkillHook):
    """Raise ``KeyboardInterrupt`` before an iteration (in-process crash)."""

    def before_train_iter(self, runner, batch_idx, data_batch=None):
        if runner.iter == self.at_iter:
            raise KeyboardInterrupt(f'test crash at iteration {runner.iter}')


@HOOKS.register_module(force=True)
class CBNetTestDumpRankWeightsHook(Hook):
    """Every rank saves its weights before and after training, to
    ``{work_dir}/rank{rank}_{before,after}.pth``."""

    priority = 'LOWEST'  # after the other hooks' before_/after_train

    @staticmethod
    def _dump(runner, when):
        model = runner.model
        if is_model_wrapper(model):
            model = model.module
        torch.save(model.state_dict(),
                   osp.join(runner.work_dir, f'rank{get_rank()}_{when}.pth'))

    def before_train(self, runner):
        self._dump(runner, 'before')

    def after_train(self, runner):
        self._dump(runner, 'after')


@MODELS.register_module(force=True)
class CBNetTestToyModel(BaseModel):
    """Linear regression of [1, 1] to 1 whose loss is multiplied per call.

    Args:
        loss_scale (dict, optional): 1-based call -> factor of that
            call's loss (keys and values may be strings, ``'nan'`` for a
            NaN loss).
    """

    def __init__(self, loss_scale=None):
        super().__init__()
        self.fc = torch.nn.Linear(2, 1)
        self.loss_scale = {
            int(k): float(v)
            for k, v in (loss_scale or {}).items()
        }
        self.calls = 0

    def forward(self, inputs, data_samples=None, mode='loss'):
        self.calls += 1  # the inputs do not matter: always [1, 1]
        loss = ((self.fc(torch.ones(1, 2)) - 1)**2).mean()
        return dict(loss_toy=loss * self.loss_scale.get(self.calls, 1.0))


def toy_config(work_dir: str, max_iters: int = 2, lr: float = 0.01,
               custom_hooks=(), **model) -> str:
    """Write a config of :class:`CBNetTestToyModel` (4 samples, batch 1,
    a checkpoint every iteration, ``CBNetRunner`` as in
    ``configs/_base_/default_runtime.py``) for ``tools/train.py``; returns
    its path (``{work_dir}.py``)."""
    text = f'''
custom_imports = dict(imports=['cbnet_mmdet', 'helper_hooks'],
                      allow_failed_imports=False)
default_scope = 'mmdet'
runner_type = 'mmdet.CBNetRunner'
custom_hooks = {list(custom_hooks)!r}
model = dict(type='CBNetTestToyModel', **{model!r})
train_dataloader = dict(
    dataset=[dict(inputs=[1.0, 2.0])] * 4,
    sampler=dict(type='DefaultSampler', shuffle=False),
    collate_fn=dict(type='default_collate'), batch_size=1, num_workers=0)
optim_wrapper = dict(optimizer=dict(type='SGD', lr={lr!r}))
train_cfg = dict(by_epoch=False, max_iters={max_iters})
default_hooks = dict(
    checkpoint=dict(type='CheckpointHook', interval=1, by_epoch=False),
    logger=dict(type='LoggerHook', interval=1))
randomness = dict(seed=0)
experiment_name = {'toy_' + uuid.uuid4().hex!r}  # its own logger
'''
    path = work_dir.rstrip('/') + '.py'
    with open(path, 'w') as f:
        f.write(text)
    return path


def toy_runner(work_dir, hook, max_iters=6, runner=None, **loss_scale):
    """An MMEngine ``Runner`` (or ``runner``, a subclass) of
    :class:`CBNetTestToyModel` with a checkpoint every iteration and
    ``hook``; ``loss_scale``: ``it3=1e4`` multiplies the 3rd loss."""
    from mmengine.runner import Runner
    scale = {k[2:]: v for k, v in loss_scale.items()}
    return (runner or Runner)(
        model=CBNetTestToyModel(loss_scale=scale),
        work_dir=str(work_dir),
        train_dataloader=dict(
            dataset=[dict(inputs=torch.ones(2))] * 8,
            sampler=dict(type='DefaultSampler', shuffle=False),
            collate_fn=dict(type='pseudo_collate'),
            batch_size=1),
        optim_wrapper=dict(optimizer=dict(type='SGD', lr=0.01)),
        train_cfg=dict(by_epoch=False, max_iters=max_iters),
        default_hooks=dict(checkpoint=dict(
            type='CheckpointHook', interval=1, by_epoch=False)),
        custom_hooks=[hook],
        default_scope='mmdet',
        experiment_name='toy_' + uuid.uuid4().hex)
