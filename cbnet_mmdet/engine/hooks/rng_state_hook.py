"""Save the random generators in checkpoints so a resume is exact."""
import random
from typing import List, Optional

import numpy as np
import torch
from mmdet.registry import HOOKS
from mmengine.dist import all_gather_object, get_dist_info
from mmengine.hooks import CheckpointHook, Hook
from mmengine.runner import Runner

#: Checkpoint key holding one RNG state per rank.
CHECKPOINT_KEY = 'rng_state'


def get_rng_state() -> dict:
    """The state of Python's, NumPy's, torch's (and CUDA's) generators.

    NumPy's key array is stored as a tensor so the state loads with
    ``torch.load(weights_only=True)`` without more allow-listed globals.

    Returns:
        dict: ``python``, ``numpy``, ``torch`` and, where CUDA is
        initialised, ``cuda`` (one state per device).
    """
    name, keys, pos, has_gauss, cached = np.random.get_state()
    state = dict(
        python=random.getstate(),
        numpy=(name, torch.from_numpy(keys.astype(np.int64)), pos,
               has_gauss, cached),
        torch=torch.get_rng_state())
    if torch.cuda.is_available() and torch.cuda.is_initialized():
        state['cuda'] = torch.cuda.get_rng_state_all()
    return state


def set_rng_state(state: dict) -> None:
    """Restore what :func:`get_rng_state` returned."""
    random.setstate(state['python'])
    name, keys, pos, has_gauss, cached = state['numpy']
    np.random.set_state(
        (name, keys.numpy().astype(np.uint32), pos, has_gauss, cached))
    torch.set_rng_state(state['torch'])
    if 'cuda' in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state['cuda'])


@HOOKS.register_module()
class CBNetRNGStateHook(Hook):
    """Checkpoint the random generators so ``--resume`` continues exactly.

    MMEngine restores the model, the optimizer, the schedulers and the
    iteration on resume, and re-seeds the generators with the run's seed:
    the resumed run then draws different random numbers than the
    uninterrupted one would have (RandomFlip, RoI sampling, drop-path), and
    ends with different weights. This hook stores the state of Python's,
    NumPy's, torch's and CUDA's generators under ``checkpoint['rng_state']``
    (one entry per rank) and restores it at the start of a resumed run, so
    that a run killed and resumed ends bitwise like an uninterrupted one
    (tested on CPU with an epoch-based loop).

    Exactness needs the same world size on resume (otherwise the states
    are not restored and a warning is logged), and the data pipeline's
    randomness to be either in the main process (``num_workers=0``) or in
    workers, which MMEngine seeds identically every epoch. An iteration
    checkpoint in the middle of an epoch-based loop cannot resume exactly
    whatever the generators (MMEngine restarts the epoch's data); with
    ``IterBasedTrainLoop`` and ``num_workers=0`` the batches MMEngine skips
    on resume go through the pipeline again and consume random numbers.

    In distributed runs the states are gathered from all ranks where the
    ``CheckpointHook`` will save (every epoch end, and at its iteration
    interval when it saves by iteration): one small collective each time.
    """

    priority = 'LOW'  # before CheckpointHook (VERY_LOW) saves

    def __init__(self) -> None:
        self._gathered: Optional[List[dict]] = None
        self._loaded: Optional[List[dict]] = None

    # -- saving -----------------------------------------------------------
    @staticmethod
    def _checkpoint_hook(runner: Runner) -> Optional[CheckpointHook]:
        for hook in runner.hooks:
            if isinstance(hook, CheckpointHook):
                return hook
        return None

    def _gather(self, runner: Runner) -> None:
        _, world_size = get_dist_info()
        if world_size > 1:
            self._gathered = all_gather_object(get_rng_state())

    def after_train_iter(self, runner: Runner, batch_idx: int,
                         data_batch=None, outputs=None) -> None:
        """Gather the ranks' states where an iteration checkpoint follows."""
        ckpt = self._checkpoint_hook(runner)
        if ckpt is None or ckpt.by_epoch:
            return
        if (ckpt.every_n_train_iters(runner, ckpt.interval, ckpt.save_begin)
                or (ckpt.save_last and ckpt.is_last_train_iter(runner))):
            self._gather(runner)

    def after_train_epoch(self, runner: Runner) -> None:
        """Gather the ranks' states (distributed runs) at every epoch end."""
        self._gather(runner)

    def before_save_checkpoint(self, runner: Runner,
                               checkpoint: dict) -> None:
        """Write ``checkpoint['rng_state']``: a list with one state per
        rank."""
        _, world_size = get_dist_info()
        if world_size == 1:
            checkpoint[CHECKPOINT_KEY] = [get_rng_state()]
        elif self._gathered is not None:
            checkpoint[CHECKPOINT_KEY] = self._gathered
        self._gathered = None

    # -- restoring --------------------------------------------------------
    def after_load_checkpoint(self, runner: Runner, checkpoint: dict) -> None:
        """Keep the saved states; they are applied in ``before_train``."""
        self._loaded = checkpoint.get(CHECKPOINT_KEY)

    def before_train(self, runner: Runner) -> None:
        """Restore this rank's generators when the run was resumed.

        ``before_train`` follows model initialisation and checkpoint
        loading, which draw random numbers of their own; a fresh run
        (``runner.iter == 0``) or ``load_from`` (fine-tuning) is left
        alone.
        """
        states, self._loaded = self._loaded, None
        if runner.iter == 0:
            return
        rank, world_size = get_dist_info()
        if not states:
            runner.logger.warning(
                'CBNetRNGStateHook: the resumed checkpoint holds no RNG '
                'state; training continues, but not bitwise as without '
                'the interruption')
        elif len(states) != world_size:
            runner.logger.warning(
                f'CBNetRNGStateHook: the checkpoint holds RNG states of '
                f'{len(states)} rank(s) but this run has {world_size}; the '
                f'generators are not restored')
        else:
            set_rng_state(states[rank])
            runner.logger.info('CBNetRNGStateHook: random generators '
                               'restored from the checkpoint')
