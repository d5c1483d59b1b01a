"""MMEngine's Runner with checked checkpoint loading."""
from mmdet.registry import RUNNERS
from mmengine.runner import Runner

from cbnet_mmdet.utils.checkpoint.files import (diverged_problem,
                                                read_checkpoint,
                                                resume_checkpoint)
from cbnet_mmdet.utils.checkpoint.safe_globals import mmengine_safe_globals


@RUNNERS.register_module()
class CBNetRunner(Runner):
    """``Runner`` whose ``resume`` / ``load_from`` name the file and the
    problem, never resume diverged weights, and whose auto-resume survives
    damaged and moved work dirs.

    The one place where training and testing load checkpoints:

    * ``resume=True`` without ``load_from`` (``--resume``): the checkpoint
      ``work_dir/last_checkpoint`` names, looked up INSIDE the work dir
      (MMEngine writes an absolute path, so a copied work dir would resume
      from the original folder's file); when it is damaged (truncated by a
      kill during the save, ...) or was written after training diverged
      (``CBNetNonFiniteLossHook`` records which), the newest intact clean
      checkpoint of the work dir, with a warning saying so; a diverged run
      without a clean checkpoint is refused;
    * ``resume=True`` with ``load_from`` (``--resume PATH``): the file is
      checked first; a damaged, foreign (a bare state dict), diverged or
      non-checkpoint file raises one error naming it, the problem and the
      newest intact checkpoint of the work dir;
    * ``load_from`` alone: the file is checked before MMEngine loads it;
      any dict of tensors may be loaded, except a checkpoint that the
      divergence record of its folder names (by content, so a copied work
      dir keeps it) as written after the weights went bad: refused as
      ``--resume`` refuses it.

    MMEngine's loading runs inside
    :func:`~cbnet_mmdet.utils.checkpoint.safe_globals.mmengine_safe_globals`
    (weights-only, with MMEngine's allow-list for these calls only).
    ``configs/_base_/default_runtime.py`` names it (``runner_type``), so
    MMDetection's ``tools/train.py`` / ``tools/test.py`` and ``mim train``
    build it as the project's tools do.
    """

    def load_or_resume(self) -> None:
        """Check, then resume or load (see the class docstring)."""
        if self._has_loaded:
            return
        if self._resume:
            path, notes = resume_checkpoint(self.work_dir, self._load_from)
            for note in notes:
                self.logger.warning(f'resume: {note}')
            if path is not None:
                if self._load_from is None:
                    self.logger.info(f'Auto resumed from {path}')
                self.resume(path)
                self._has_loaded = True
                return
            self.logger.info('resume: no checkpoint in the work dir '
                             f'{self.work_dir}; training from scratch')
        if self._load_from is not None:
            problem = diverged_problem(self._load_from)
            if problem:
                raise ValueError(f'load_from {self._load_from}: {problem}')
            self.load_checkpoint(self._load_from)
            self._has_loaded = True

    def load_checkpoint(self, filename: str, *args, **kwargs) -> dict:
        """MMEngine's, after the file check (local files), weights-only
        with MMEngine's allow-list."""
        if '://' not in filename:
            read_checkpoint(filename, mmap=True)  # named errors
        with mmengine_safe_globals():
            return super().load_checkpoint(filename, *args, **kwargs)

    def resume(self, filename: str, *args, **kwargs) -> None:
        """MMEngine's, weights-only with MMEngine's allow-list."""
        with mmengine_safe_globals():
            super().resume(filename, *args, **kwargs)
