"""Does a checkpoint fit a model? Refuse one that does not, at inference.

MMEngine loads weights non-strictly: tensors with the wrong shape or name
are skipped with a printed warning, and the model then predicts with
random weights where the checkpoint did not fit (the MiT-B0 demo
checkpoint in the MiT-B5 config returns boxes at score 1.0; a CBNet-DD
checkpoint in the plain config loads nothing at all). MMDetection's
``init_detector`` and ``DetInferencer`` do exactly that, with our configs
too: the models do not check where their weights come from. Where the
project loads weights to evaluate them, they are checked:

* :func:`check_checkpoint_fits` compares a whole checkpoint with a model
  and raises :class:`CheckpointMismatchError` saying what does not fit and
  what to do: ``tools/test.py`` and the tools built on MMEngine's runner,
  through ``CBNetCheckpointReportHook(require_fit=True)``
  (:func:`require_checkpoint_fit`), and the project's inference tools
  through :func:`init_checked_detector`.
"""
from typing import Dict, List, Optional

#: Names listed per category in messages (counts are always given).
MAX_LISTED = 10
#: Where a CBNet-DD (``CBNetDistiller``) checkpoint keeps its detectors.
DISTILLER_PREFIXES = ('student.', 'teacher.')
#: What to run on a CBNet-DD checkpoint.
EXTRACT_HINT = ('it is a CBNet-DD (CBNetDistiller) checkpoint: export its '
                'student first with `python tools/model_converters/'
                'extract_student.py CKPT student.pth` and use student.pth '
                'with the plain CBNet config')
#: What to do with a checkpoint of another model.
CONFIG_HINT = ('use the config the checkpoint was trained with (a '
               'checkpoint written by tools/train.py embeds it: '
               '`DetInferencer(weights=CKPT)` without a config uses it)')


class CheckpointMismatchError(ValueError):
    """A checkpoint whose weights do not fit the model it is loaded into."""


def compare_state_dicts(model_state: Dict,
                        ckpt_state: Dict) -> Dict[str, List[str]]:
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


def listed(names: List[str]) -> str:
    """The first :data:`MAX_LISTED` names and how many more there are."""
    more = len(names) - MAX_LISTED
    return ', '.join(names[:MAX_LISTED]) + (f' ... (+{more})'
                                            if more > 0 else '')


def misfit_message(report: Dict[str, List[str]], source: str, target: str,
                   ckpt_keys: Optional[List[str]] = None) -> str:
    """Say what of ``source`` does not fit ``target`` and what to do.

    Args:
        report (dict): :func:`compare_state_dicts`'s result.
        source (str): The checkpoint (file name, for the message).
        target (str): What it was loaded into (for the message).
        ckpt_keys (list[str], optional): All of the checkpoint's keys, to
            recognise a CBNet-DD checkpoint.

    Returns:
        str: The message (several lines).
    """
    total = len(report['loaded']) + len(report['missing']) + len(
        report['mismatched'])
    lines = [f'the checkpoint {source} does not fit {target}: '
             f'{len(report["loaded"])} of the {total} tensors it needs fit']
    for key in ('mismatched', 'missing', 'unexpected'):
        if report[key]:
            lines.append(f'  {key} ({len(report[key])}): '
                         f'{listed(report[key])}')
    keys = report['unexpected'] if ckpt_keys is None else ckpt_keys
    distiller = bool(keys) and all(
        k.startswith(DISTILLER_PREFIXES) for k in keys)
    if distiller or any(k.startswith(DISTILLER_PREFIXES)
                        for k in report['unexpected']):
        lines.append(f'What to do: {EXTRACT_HINT}.')
    else:
        lines.append(f'What to do: {CONFIG_HINT}.')
    return '\n'.join(lines)


def check_checkpoint_fits(model_state: Dict,
                          ckpt_state: Dict,
                          source: str = 'the checkpoint',
                          target: str = 'the model') -> Dict[str, List[str]]:
    """Refuse a checkpoint that does not fill the whole model.

    Every tensor of the model must be in the checkpoint with the same
    shape (BN ``num_batches_tracked`` aside). Extra tensors in the
    checkpoint are allowed (they are reported by the caller's log).

    Args:
        model_state (dict[str, Tensor]): ``model.state_dict()``.
        ckpt_state (dict[str, Tensor]): The checkpoint's ``state_dict``.
        source (str): The checkpoint's name, for the message.
        target (str): The model's name, for the message.

    Returns:
        dict[str, list[str]]: :func:`compare_state_dicts`'s report.

    Raises:
        CheckpointMismatchError: a model tensor is missing from the
            checkpoint or has another shape there.
    """
    report = compare_state_dicts(model_state, ckpt_state)
    if report['missing'] or report['mismatched']:
        raise CheckpointMismatchError(
            misfit_message(report, source, target, list(ckpt_state)))
    return report


def init_checked_detector(config, checkpoint: str, device: str = 'cpu'):
    """MMDetection's ``init_detector``, refusing a checkpoint that does not
    fill the model (the project's inference tools).

    Args:
        config (str | Config): The detector's config.
        checkpoint (str): Local checkpoint file (read weights-only, with
            MMEngine's allow-list for this call only).
        device (str): Where the model runs.

    Returns:
        nn.Module: The model, in eval mode, with the checkpoint loaded.

    Raises:
        CheckpointMismatchError: a model tensor is missing from the
            checkpoint or has another shape there.
    """
    from mmdet.apis import init_detector

    from .files import read_checkpoint, unwrap_state_dict
    from .safe_globals import mmengine_safe_globals
    state = unwrap_state_dict(read_checkpoint(checkpoint, mmap=True))
    try:
        with mmengine_safe_globals():
            model = init_detector(config, checkpoint, device=device)
    except CheckpointMismatchError as err:
        # a component refused its part (models/utils/state_dict_fit.py):
        # say what of the whole model does not fit, naming the file
        model = init_detector(config, None, device='cpu')
        check_checkpoint_fits(model.state_dict(), state, checkpoint,
                              type(model).__name__)
        raise err
    check_checkpoint_fits(model.state_dict(), state, checkpoint,
                          type(model).__name__)
    return model


def require_checkpoint_fit(cfg) -> None:
    """Make a runner config refuse a checkpoint that does not fit its model.

    Sets ``require_fit=True`` on the config's ``CBNetCheckpointReportHook``
    (adding the hook under ``default_hooks.checkpoint_report`` when the
    config has none), for runners that evaluate ``cfg.load_from``.

    Args:
        cfg (Config): A runner config; changed in place.
    """
    hooks = cfg.get('default_hooks')
    if hooks is None:
        cfg.default_hooks = hooks = {}
    for key, hook in hooks.items():
        if hook is not None and hook.get('type') in (
                'CBNetCheckpointReportHook',
                'mmdet.CBNetCheckpointReportHook'):
            hook['require_fit'] = True
            return
    hooks['checkpoint_report'] = dict(
        type='CBNetCheckpointReportHook', require_fit=True)
