"""Log (and refuse) checkpoints whose weights do not fit the model."""
from typing import List, Tuple

from mmdet.registry import HOOKS
from mmengine.hooks import Hook
from mmengine.model import is_model_wrapper
from mmengine.runner import Runner

from cbnet_mmdet.utils.checkpoint.fit import (check_checkpoint_fits,
                                              compare_state_dicts, listed,
                                              misfit_message)


@HOOKS.register_module()
class CBNetCheckpointReportHook(Hook):
    """Say in the log what of a ``load_from``/``--resume`` checkpoint did
    not load, and stop when nothing of it fits.

    MMEngine loads checkpoints non-strictly and reports mismatches with a
    bare ``print`` (not in the log file) in a single long paragraph. This
    hook logs, before the weights are copied, a one-line summary (``N of M
    model tensors loaded``) and, as a warning, the missing, unexpected and
    shape-mismatched tensors (the first
    :data:`cbnet_mmdet.utils.checkpoint.fit.MAX_LISTED` of each, with
    counts). A checkpoint of which no tensor fits (the wrong file, another
    architecture) raises ``ValueError`` naming it, instead of training from
    scratch without notice.

    With ``require_fit=True`` (``tools/test.py`` and the other tools that
    evaluate a checkpoint) every model tensor must be in the checkpoint
    with its shape: a partial fit raises
    :class:`~cbnet_mmdet.utils.checkpoint.fit.CheckpointMismatchError`
    saying what does not fit and what to do (extract the student of a
    CBNet-DD checkpoint, use the checkpoint's own config).

    Args:
        allow_no_match (bool): Only warn when no tensor fits. Defaults to
            False.
        require_fit (bool): Refuse a checkpoint that does not fill the
            whole model (for evaluation; training's ``load_from`` may
            fine-tune from a partial fit). Defaults to False.
    """

    priority = 'VERY_HIGH'

    def __init__(self, allow_no_match: bool = False,
                 require_fit: bool = False) -> None:
        self.allow_no_match = allow_no_match
        self.require_fit = require_fit

    def after_load_checkpoint(self, runner: Runner, checkpoint: dict) -> None:
        """Compare ``checkpoint['state_dict']`` with the model and log.

        Raises:
            ValueError: No tensor of the checkpoint fits the model and
                ``allow_no_match`` is False.
        """
        model = runner.model.module if is_model_wrapper(runner.model) \
            else runner.model
        state = checkpoint.get('state_dict', checkpoint)
        name = getattr(runner, '_load_from', None) or 'the checkpoint'
        model_state = model.state_dict()
        if self.require_fit:
            check_checkpoint_fits(model_state, state, name,
                                  type(model).__name__)
        report = compare_state_dicts(model_state, state)
        total = len(report['loaded']) + len(report['missing']) + len(
            report['mismatched'])
        runner.logger.info(
            f'CBNetCheckpointReportHook: {len(report["loaded"])} of {total} '
            f'model tensors loaded from {name}')
        problems: List[Tuple[str, List[str]]] = [
            (k, report[k]) for k in ('missing', 'unexpected', 'mismatched')
            if report[k]
        ]
        if problems:
            runner.logger.warning(
                'CBNetCheckpointReportHook: not loaded from ' + name + ':\n'
                + '\n'.join(f'  {k} ({len(v)}): {listed(v)}'
                            for k, v in problems))
        if not report['loaded'] and not self.allow_no_match:
            raise ValueError(
                f'no tensor of {name} fits the model '
                f'({type(model).__name__}); is it a checkpoint of this '
                f'architecture? (set allow_no_match=True in '
                f'CBNetCheckpointReportHook to train anyway)\n' +
                misfit_message(report, name, type(model).__name__,
                               list(state)))
