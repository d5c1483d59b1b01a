"""Log (and refuse) checkpoints whose weights do not fit the model."""
from typing import Dict, List, Tuple

from mmdet.registry import HOOKS
from mmengine.hooks import Hook
from mmengine.model import is_model_wrapper
from mmengine.runner import Runner

#: Names listed per category in the log (counts are always given).
MAX_LISTED = 10


def compare_state_dicts(
        model_state: Dict, ckpt_state: Dict) -> Dict[str, List[str]]:
    """What of a checkpoint loads into a model, by name and shape.

    Args:
        model_state (dict[str, Tensor]): ``model.state_dict()``.
        ckpt_state (dict[str, Tensor]): The checkpoint's weights (a
            ``module.`` prefix, as DDP writes it, is ignored).

    Returns:
        dict[str, list[str]]: ``loaded``, ``missing`` (in the model, not
        in the checkpoint; BN ``num_batches_tracked`` ignored),
        ``unexpected`` (in the checkpoint only) and ``mismatched``
        (``'name: checkpoint (shape) vs model (shape)'``).
    """
    ckpt = {(k[len('module.'):] if k.startswith('module.') else k): v
            for k, v in ckpt_state.items()}
    shape = lambda v: tuple(getattr(v, 'shape', ()))  # noqa: E731
    common = [k for k in model_state if k in ckpt]
    mismatched = [
        f'{k}: checkpoint {shape(ckpt[k])} vs model {shape(model_state[k])}'
        for k in common if shape(ckpt[k]) != shape(model_state[k])
    ]
    bad = {m.split(':')[0] for m in mismatched}
    return dict(
        loaded=[k for k in common if k not in bad],
        missing=[
            k for k in model_state
            if k not in ckpt and not k.endswith('num_batches_tracked')
        ],
        unexpected=[k for k in ckpt if k not in model_state],
        mismatched=mismatched)


def _listed(names: List[str]) -> str:
    more = len(names) - MAX_LISTED
    return ', '.join(names[:MAX_LISTED]) + (f' ... (+{more})'
                                            if more > 0 else '')


@HOOKS.register_module()
class CBNetCheckpointReportHook(Hook):
    """Say in the log what of a ``load_from``/``--resume`` checkpoint did
    not load, and stop when nothing of it fits.

    MMEngine loads checkpoints non-strictly and reports mismatches with a
    bare ``print`` (not in the log file) in a single long paragraph. This
    hook logs, before the weights are copied, a one-line summary (``N of M
    model tensors loaded``) and, as a warning, the missing, unexpected and
    shape-mismatched tensors (first :data:`MAX_LISTED` of each, with
    counts). A checkpoint of which no tensor fits (the wrong file, another
    architecture) raises ``ValueError`` naming it, instead of training from
    scratch without notice.

    Args:
        allow_no_match (bool): Only warn when no tensor fits. Defaults to
            False.
    """

    priority = 'VERY_HIGH'

    def __init__(self, allow_no_match: bool = False) -> None:
        self.allow_no_match = allow_no_match

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
        report = compare_state_dicts(model.state_dict(), state)
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
                + '\n'.join(f'  {k} ({len(v)}): {_listed(v)}'
                            for k, v in problems))
        if not report['loaded'] and not self.allow_no_match:
            raise ValueError(
                f'no tensor of {name} fits the model '
                f'({type(model).__name__}); is it a checkpoint of this '
                f'architecture? (missing {len(report["missing"])}, '
                f'unexpected {len(report["unexpected"])}, shape mismatches '
                f'{len(report["mismatched"])}; set allow_no_match=True in '
                f'CBNetCheckpointReportHook to train anyway)')
