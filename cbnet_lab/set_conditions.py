"""What a set's runs are tested on besides their own test set: a set
file's optional ``transfer_test``, a second (real-fog) test set, checked
(read by :mod:`cbnet_lab.sets`, which imports this module; it imports
nothing of the lab but :func:`cbnet_lab.set_device.only_keys`)."""
from typing import Optional

from .set_device import only_keys

#: The keys of a set's ``transfer_test``: the condition's name and the VOC
#: folder are required, the rest are :class:`CBNetVOCFogDataset`'s split
#: arguments (:func:`cbnet_lab.config_edits.transfer_cfg`).
TRANSFER_KEYS = ('condition', 'data_root', 'split', 'val_fraction',
                 'split_seed', 'ann_file', 'img_suffix')


def transfer_test(path: str, value) -> Optional[dict]:
    """A set file's ``transfer_test`` (read from ``path``; None: no second
    test set), checked.

    Raises:
        ValueError: Not a dict of :data:`TRANSFER_KEYS`, or without a
            non-empty ``condition`` or ``data_root``.
    """
    if value is None:
        return None
    where = f'{path}: transfer_test'
    spec = dict(only_keys(where, value, TRANSFER_KEYS, 'it'))
    for key in ('condition', 'data_root'):
        if not isinstance(spec.get(key), str) or not spec[key].strip():
            raise ValueError(f'{where} needs a non-empty {key!r}, got '
                             f'{spec.get(key)!r}')
    return spec
