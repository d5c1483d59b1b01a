"""What a set's runs are tested on, by name: the presets file's
``test_conditions`` (the name a real-data folder's test split is reported
under) and a set file's optional ``transfer_test`` (a second, real-fog
test set), checked (read by :mod:`cbnet_lab.sets`, which imports this
module; it imports nothing of the lab but
:func:`cbnet_lab.set_device.only_keys`)."""
from typing import Dict, Optional

from .set_device import only_keys

#: The keys of a set's ``transfer_test``: the condition's name and the VOC
#: folder are required, the rest are :class:`CBNetVOCFogDataset`'s split
#: arguments (:func:`cbnet_lab.config_edits.transfer_cfg`).
TRANSFER_KEYS = ('condition', 'data_root', 'split', 'val_fraction',
                 'split_seed', 'ann_file', 'img_suffix')


def _is_name(value) -> bool:
    return isinstance(value, str) and bool(value.strip())


def conditions_by_folder(path: str, spec: dict) -> Dict[str, str]:
    """The presets file's ``test_conditions`` (``spec``, read from
    ``path``): a real-data folder's name (its ``data_root``'s last
    folder) -> the name its test split is reported under, checked.

    Raises:
        ValueError: A key that is no folder's name, or a name that is
            empty or one of the Cityscapes-layout data's (``clear``,
            ``foggy beta=B``).
    """
    for folder, name in spec.items():
        where = f'{path}: test_conditions {folder!r}'
        if not _is_name(folder) or '/' in folder:
            raise ValueError(f'{where}: the key must be a data folder\'s '
                             'name (its data_root\'s last folder)')
        if not _is_name(name) or name == 'clear' or \
                name.startswith('foggy beta='):
            raise ValueError(
                f'{where}: the name of its test split must be a non-empty '
                "name other than the Cityscapes-layout data's ('clear', "
                f"'foggy beta=B'), got {name!r}")
    return dict(spec)


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
        if not _is_name(spec.get(key)):
            raise ValueError(f'{where} needs a non-empty {key!r}, got '
                             f'{spec.get(key)!r}')
    return spec
