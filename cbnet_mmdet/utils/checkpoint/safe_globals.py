"""Let ``torch.load(weights_only=True)`` read MMEngine checkpoints, inside
a context only.

torch >= 2.6 loads with ``weights_only=True`` by default, and MMEngine 0.10.7
loads checkpoints with the default, so ``resume`` of a checkpoint MMEngine
wrote fails out of the box.
Besides tensors, MMEngine writes into ``message_hub``/``meta``:

* ``mmengine.logging.history_buffer.HistoryBuffer`` (the logged scalars),
* NumPy arrays and scalars (``numpy.ndarray``, ``numpy.dtype``,
  ``numpy.core.multiarray._reconstruct``, ``numpy.core.multiarray.scalar``)
  and the dtype classes they are built with (``numpy.dtypes.Float64DType``
  for the logged values; we allow the plain numeric dtypes, since a
  ``HistoryBuffer`` keeps whatever numeric type was logged),
* ``builtins.getattr``: a ``HistoryBuffer`` pickles its statistics methods
  (``HistoryBuffer.min`` ...) as ``getattr(HistoryBuffer, 'min')``.

The list was read with ``torch.serialization.get_unsafe_globals_in_checkpoint``
from the checkpoints of a real run; a test repeats that and fails when
MMEngine starts writing something else. We allow exactly these. The real
``getattr`` is never allowed (with it a checkpoint could reach any
attribute, and so run code): a stand-in registered under its name resolves
only ``HistoryBuffer``'s statistics methods and refuses everything else. We
never turn ``weights_only`` off, which would let a downloaded checkpoint run
code.

Nothing here changes torch for the whole process: importing
``cbnet_mmdet`` adds no safe global. :func:`mmengine_safe_globals` is a
``torch.serialization.safe_globals`` context, entered by ``CBNetRunner``
(``load_from``, ``--resume``) and :func:`~cbnet_mmdet.utils.checkpoint.
files.read_checkpoint` around their own loading only; a script of yours
can enter it around ``init_detector`` / ``DetInferencer`` for a checkpoint
written without ``CBNetWeightsOnlyCheckpointHook``.
"""
import pickle

import numpy as np
import torch
from mmengine.logging.history_buffer import HistoryBuffer

#: Numeric dtypes whose classes may appear in logged arrays/scalars.
_NUMERIC_DTYPES = ('bool', 'int8', 'int16', 'int32', 'int64', 'uint8',
                   'uint16', 'uint32', 'uint64', 'float16', 'float32',
                   'float64')

#: The statistics methods HistoryBuffer pickles by attribute name.
_HISTORY_BUFFER_METHODS = frozenset(('min', 'max', 'current', 'mean'))


def history_buffer_getattr(obj, name):
    """Stand-in for ``builtins.getattr`` inside weights-only unpickling.

    Args:
        obj: must be the ``HistoryBuffer`` class.
        name (str): one of its statistics methods (min, max, current, mean).

    Returns:
        The function ``HistoryBuffer.<name>``.

    Raises:
        pickle.UnpicklingError: for any other object or attribute.
    """
    if obj is HistoryBuffer and name in _HISTORY_BUFFER_METHODS:
        return getattr(HistoryBuffer, name)
    raise pickle.UnpicklingError(
        f'checkpoint asks for getattr({obj!r}, {name!r}); cbnet_mmdet only '
        f'allows HistoryBuffer statistics methods '
        f'{sorted(_HISTORY_BUFFER_METHODS)} in weights-only loading')


def mmengine_checkpoint_globals() -> list:
    """The allow-list, in ``torch.serialization.add_safe_globals`` form."""
    multiarray = np.core.multiarray
    return [
        HistoryBuffer,
        np.ndarray,
        np.dtype,
        (multiarray._reconstruct, 'numpy.core.multiarray._reconstruct'),
        (multiarray.scalar, 'numpy.core.multiarray.scalar'),
        (history_buffer_getattr, 'builtins.getattr'),
        *(type(np.dtype(name)) for name in _NUMERIC_DTYPES),
    ]


def allowed_global_names() -> set:
    """Full names of the allow-listed globals, as checkpoints spell them."""
    names = set()
    for item in mmengine_checkpoint_globals():
        if isinstance(item, tuple):
            names.add(item[1])
        else:
            names.add(f'{item.__module__}.{item.__qualname__}')
    return names


def mmengine_safe_globals() -> torch.serialization.safe_globals:
    """A context inside which weights-only loading reads MMEngine
    checkpoints (the allow-list above); torch's list is as before after
    it."""
    return torch.serialization.safe_globals(mmengine_checkpoint_globals())
