"""Write checkpoints that torch's default ``weights_only`` loading reads."""
from typing import Any

import numpy as np
import torch
from mmdet.registry import HOOKS
from mmengine.hooks import Hook
from mmengine.logging.history_buffer import HistoryBuffer
from mmengine.runner import Runner

#: Key of the dicts that stand for a non-tensor object in a checkpoint.
TAG = '__cbnet_mmdet__'


def _ndarray_to_tensor(array: np.ndarray):
    """The array as a tensor of its dtype, or None when torch has none."""
    try:
        # a C-ordered copy; np.ascontiguousarray would make 0-d arrays 1-d
        return torch.from_numpy(np.array(array, order='C'))
    except TypeError:  # object, string ... arrays: left as they are
        return None


def to_weights_only(obj: Any) -> Any:
    """Replace what ``torch.load(weights_only=True)`` cannot read.

    MMEngine's message hub holds ``HistoryBuffer`` objects (the logged
    scalars) built on NumPy arrays, and NumPy values may sit anywhere in
    ``meta`` or the runtime information. Each becomes a small dict
    ``{TAG: kind, ...}`` of tensors and Python numbers; containers (dict,
    list, tuple) are rebuilt with their converted items. Tensors and other
    values are kept as they are. :func:`from_weights_only` reverses it
    exactly (values, dtypes and shapes).

    Args:
        obj: Any part of a checkpoint.

    Returns:
        The converted object (a new container where something changed).
    """
    if isinstance(obj, HistoryBuffer):
        log, count = obj.data
        return {
            TAG: 'HistoryBuffer',
            'log_history': to_weights_only(log),
            'count_history': to_weights_only(count),
            'max_length': obj.max_length
        }
    if isinstance(obj, np.ndarray):
        tensor = _ndarray_to_tensor(obj)
        return obj if tensor is None else {TAG: 'ndarray', 'data': tensor}
    if isinstance(obj, np.generic):
        tensor = _ndarray_to_tensor(np.asarray(obj))
        return obj if tensor is None else {TAG: 'numpy_scalar',
                                           'data': tensor}
    if isinstance(obj, dict):
        return type(obj)((k, to_weights_only(v)) for k, v in obj.items())
    if isinstance(obj, (list, tuple)) and not hasattr(obj, '_fields'):
        return type(obj)(to_weights_only(v) for v in obj)
    return obj


def from_weights_only(obj: Any) -> Any:
    """Undo :func:`to_weights_only` (a checkpoint without its dicts is
    returned unchanged)."""
    if isinstance(obj, dict):
        kind = obj.get(TAG)
        if kind == 'HistoryBuffer':
            return HistoryBuffer(
                from_weights_only(obj['log_history']),
                from_weights_only(obj['count_history']), obj['max_length'])
        # the runner resumes with map_location=its device: on a GPU the
        # tensors arrive there, and NumPy needs them on the host
        if kind == 'ndarray':
            return obj['data'].cpu().numpy()
        if kind == 'numpy_scalar':
            return obj['data'].cpu().numpy()[()]
        return type(obj)((k, from_weights_only(v)) for k, v in obj.items())
    if isinstance(obj, (list, tuple)) and not hasattr(obj, '_fields'):
        return type(obj)(from_weights_only(v) for v in obj)
    return obj


@HOOKS.register_module()
class CBNetWeightsOnlyCheckpointHook(Hook):
    """Make checkpoints load with ``torch.load``'s default ``weights_only``.

    torch >= 2.6 loads with ``weights_only=True``; MMEngine writes its
    message hub (``HistoryBuffer`` objects on NumPy arrays) into every
    training checkpoint, which such loading refuses outside the allow-list
    of :mod:`cbnet_mmdet.utils.checkpoint.safe_globals` (a context that
    only ``CBNetRunner`` and the project's tools enter; importing
    ``cbnet_mmdet`` changes nothing in torch). MMDetection's
    ``DetInferencer(weights=CKPT)``, ``init_detector`` and
    ``demo/image_demo.py IMG CKPT`` load with torch's default: they failed
    on MMEngine's training checkpoints.

    Before a checkpoint is saved, this hook replaces everything but
    tensors and Python values by plain dicts of tensors
    (:func:`to_weights_only`); after one is loaded, before the runner
    restores the message hub, it puts the objects back
    (:func:`from_weights_only`), so ``--resume`` is unchanged. The weights
    (``state_dict``) are tensors already and are not touched. Checkpoints
    written without the hook load through ``CBNetRunner`` (its allow-list).
    """

    # last to run before saving (after every hook that adds to the
    # checkpoint); after loading, the runner reads the message hub only
    # once all hooks have run
    priority = 'LOWEST'

    def before_save_checkpoint(self, runner: Runner,
                               checkpoint: dict) -> None:
        """Convert every entry but ``state_dict``, in place."""
        for key, value in checkpoint.items():
            if key != 'state_dict':
                checkpoint[key] = to_weights_only(value)

    def after_load_checkpoint(self, runner: Runner, checkpoint: dict) -> None:
        """Restore the converted entries, in place."""
        for key, value in checkpoint.items():
            if key != 'state_dict':
                checkpoint[key] = from_weights_only(value)
