"""MMEngine's Runner with checked checkpoint loading."""
from mmdet.registry import RUNNERS
from mmengine.runner import Runner

from cbnet_mmdet.utils.checkpoint.files import (read_checkpoint,
                                                resume_checkpoint)


@RUNNERS.register_module()
class CBNetRunner(Runner):
    """``Runner`` whose ``resume`` / ``load_from`` name the file and the
    problem, and whose auto-resume survives damaged and moved work dirs.

    Only :meth:`load_or_resume` differs from MMEngine's:

    * ``resume=True`` without ``load_from`` (``tools/train.py --resume``):
      the checkpoint ``work_dir/last_checkpoint`` names, looked up INSIDE
      the work dir (MMEngine writes an absolute path, so a copied work dir
      would resume from the original folder's file); when it is damaged
      (truncated by a kill during the save, ...) the newest intact
      checkpoint of the work dir, with a warning saying so;
    * ``resume=True`` with ``load_from`` (``--resume PATH``): the file is
      checked first; a damaged, foreign (a bare state dict) or
      non-checkpoint file raises one error naming it, the problem and the
      newest intact checkpoint of the work dir;
    * ``load_from`` alone: the file is checked (weights-only, as always)
      before MMEngine loads it; any dict of tensors may be loaded.

    ``tools/train.py`` builds it unless the config names another
    ``runner_type``.
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
            if '://' not in self._load_from:
                read_checkpoint(self._load_from, mmap=True)  # named errors
            self.load_checkpoint(self._load_from)
            self._has_loaded = True
