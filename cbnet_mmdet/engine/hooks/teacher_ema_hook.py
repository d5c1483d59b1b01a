"""EMA teacher of CBNet-DD (paper section II.E)."""
from typing import Optional

import torch
import torch.nn as nn
from mmdet.engine.hooks import MeanTeacherHook
from mmdet.registry import HOOKS
from mmengine.model import is_model_wrapper
from mmengine.runner import CheckpointLoader, Runner
from mmengine.runner.checkpoint import load_state_dict

#: The submodules the hook works on.
EMA_MODELS = ('student', 'teacher')


def teacher_state_dict(checkpoint: dict, filename: str) -> dict:
    """Weights for the teacher from a loaded checkpoint.

    A ``CBNetDistiller`` checkpoint gives its ``teacher.*`` weights; any
    other detector checkpoint (e.g. CBNet trained on clear Cityscapes, the
    paper's ablation teacher) gives all its weights. A ``module.`` prefix
    (DDP) is removed.

    Args:
        checkpoint (dict): What ``CheckpointLoader.load_checkpoint`` read.
        filename (str): Its path, for error messages.

    Returns:
        dict[str, Tensor]: Weights keyed as in the student detector.
    """
    state_dict = checkpoint.get('state_dict', checkpoint)
    if not isinstance(state_dict, dict) or not state_dict:
        raise ValueError(f'CBNetTeacherEMAHook: no weights in {filename}')
    state_dict = {(k[len('module.'):] if k.startswith('module.') else k): v
                  for k, v in state_dict.items()}
    prefix = 'teacher.'
    if any(k.startswith(prefix) for k in state_dict):
        state_dict = {
            k[len(prefix):]: v
            for k, v in state_dict.items() if k.startswith(prefix)
        }
    return state_dict


@HOOKS.register_module()
class CBNetTeacherEMAHook(MeanTeacherHook):
    """Keep ``model.teacher`` an exponential moving average of the student.

    After every ``interval``-th optimizer step::

        teacher = momentum * teacher + (1 - momentum) * student

    for every parameter, and for floating-point buffers unless
    ``skip_buffers`` (integer buffers such as BN's ``num_batches_tracked``
    are copied). Note the convention: ``momentum`` is the weight of the
    *teacher* (0.999 keeps 99.9 %), as in the usual EMA-teacher papers;
    MMDetection's ``MeanTeacherHook`` calls ``1 - momentum`` its momentum.

    At the start of a fresh run (``runner.iter == 0``) the teacher is set to
    the student, or loaded from ``teacher_checkpoint`` (the paper's ablation
    uses a teacher trained on clear Cityscapes; key mismatches are logged).
    On resume nothing is re-initialised: the teacher is part of the model's
    ``state_dict``, so the runner restores the EMA from the checkpoint and
    training continues exactly as without interruption.

    Which model validation and testing run is the model's setting
    (``CBNetDistiller(eval_with=...)``), not this hook's.

    Works with ``CBNetDistiller`` (or any model with ``student`` and
    ``teacher`` submodules of the same architecture), wrapped for DDP or
    not; every rank applies the same update to the same weights, so the
    teachers stay identical without communication.

    Args:
        momentum (float): Weight of the old teacher, in (0, 1). Defaults to
            0.999.
        interval (int): Update every ``interval`` iterations. Defaults to 1.
        teacher_checkpoint (str, optional): Checkpoint (path or URL) to
            initialise the teacher from at the start of a fresh run.
            Defaults to None (a copy of the student).
        strict (bool): Raise on key mismatches of ``teacher_checkpoint``
            instead of logging them. Defaults to False.
        skip_buffers (bool): Leave the teacher's buffers (e.g. BN running
            statistics) untouched instead of averaging them. Defaults to
            False.
    """

    def __init__(self,
                 momentum: float = 0.999,
                 interval: int = 1,
                 teacher_checkpoint: Optional[str] = None,
                 strict: bool = False,
                 skip_buffers: bool = False) -> None:
        if not 0 < momentum < 1:
            raise ValueError(f'CBNetTeacherEMAHook: momentum must be in '
                             f'(0, 1), got {momentum!r}')
        if not isinstance(interval, int) or interval < 1:
            raise ValueError(f'CBNetTeacherEMAHook: interval must be a '
                             f'positive int, got {interval!r}')
        # MeanTeacherHook's momentum is the weight of the student.
        super().__init__(
            momentum=1 - momentum, interval=interval, skip_buffer=skip_buffers)
        self.teacher_checkpoint = teacher_checkpoint
        self.strict = strict

    @staticmethod
    def _unwrap(runner: Runner) -> nn.Module:
        model = runner.model
        if is_model_wrapper(model):
            model = model.module
        for name in EMA_MODELS:
            if not isinstance(getattr(model, name, None), nn.Module):
                raise TypeError(
                    f'CBNetTeacherEMAHook: the model '
                    f'({type(model).__name__}) has no `{name}` submodule; '
                    f'use CBNetDistiller')
        return model

    def before_train(self, runner: Runner) -> None:
        """Initialise the teacher at the start of a fresh run."""
        model = self._unwrap(runner)
        if runner.iter != 0:
            return  # resumed: the teacher came with the checkpoint
        if self.teacher_checkpoint is None:
            model.teacher.load_state_dict(model.student.state_dict())
            return
        checkpoint = CheckpointLoader.load_checkpoint(
            self.teacher_checkpoint, map_location='cpu')
        load_state_dict(
            model.teacher,
            teacher_state_dict(checkpoint, self.teacher_checkpoint),
            strict=self.strict,
            logger=runner.logger)
        runner.logger.info(
            f'CBNetTeacherEMAHook: teacher initialised from '
            f'{self.teacher_checkpoint}')

    @torch.no_grad()
    def momentum_update(self, model: nn.Module, momentum: float) -> None:
        """``teacher += momentum * (student - teacher)``, all tensors at once.

        Args:
            model (nn.Module): Has ``student`` and ``teacher``.
            momentum (float): Weight of the student (``1 - `` the momentum
                of this hook's config).
        """
        student = dict(model.student.named_parameters())
        teacher = dict(model.teacher.named_parameters())
        if not self.skip_buffers:
            student.update(model.student.named_buffers())
            teacher.update(model.teacher.named_buffers())
        if student.keys() != teacher.keys():
            raise RuntimeError(
                'CBNetTeacherEMAHook: student and teacher differ in '
                f'parameters: {sorted(student.keys() ^ teacher.keys())}')
        floats = [k for k, v in teacher.items() if v.is_floating_point()]
        if floats:
            torch._foreach_lerp_([teacher[k] for k in floats],
                                 [student[k].detach() for k in floats],
                                 momentum)
        for k, v in teacher.items():
            if not v.is_floating_point():
                v.copy_(student[k])
