"""Test-only hooks: a crash, a SIGKILL, and a dump of each rank's weights.

Imported by the training subprocesses through ``custom_imports`` (this
folder is put on their ``PYTHONPATH``) and by the tests themselves.
"""
import os
import os.path as osp
import signal

import torch
from mmdet.registry import HOOKS
from mmengine.dist import get_rank
from mmengine.hooks import Hook
from mmengine.model import is_model_wrapper


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
