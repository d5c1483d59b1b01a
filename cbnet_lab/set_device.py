"""How the lent GPU machine runs an experiment set
(``tools/device/run_all.py``): a set file's optional ``device`` key and the
presets file's ``device_data``, checked (read by :mod:`cbnet_lab.sets`,
which imports this module; it imports nothing of the lab)."""
import os.path as osp
import re
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

#: The keys of a set file's ``device``.
DEVICE_KEYS = ('preset', 'dry_row', 'dry_seeds', 'needs', 'tiny_weights')
#: The keys of a data folder's entry in the presets file's ``device_data``.
DEVICE_DATA_KEYS = ('make', 'tiny', 'dry_img_scale', 'val_only')
#: A writer's form, ``module:function``.
WRITER = re.compile(r'^[A-Za-z_][\w.]*:[A-Za-z_]\w*$')


@dataclass
class DeviceSpec:
    """How the lent GPU machine runs a set (its file's ``device``, with
    the defaults filled in; ``tools/device/run_all.py``).

    Attributes:
        preset (str): The preset it runs under there.
        dry_row (str, optional): The one row the dry run trains (None:
            every row).
        dry_seeds (list[int]): The dry run's seeds.
        needs (list[str]): Files its rows read, relative to the
            repository: carried with the call.
        tiny_weights (str, optional): ``module:function(folder)`` writing
            stand-ins of the pretrained files the set loads, for a dry run
            without ``--pretrained``.
    """
    preset: str
    dry_row: Optional[str]
    dry_seeds: List[int] = field(default_factory=lambda: [0])
    needs: List[str] = field(default_factory=list)
    tiny_weights: Optional[str] = None


@dataclass
class DeviceData:
    """What the lent GPU machine does with a data folder (the presets
    file's ``device_data``; the folder of a preset's ``data_root`` or
    ``transfer_root``, by its name).

    Attributes:
        name (str): The folder's name (under ``run_all.py --data``).
        make (list[str], optional): The command (the project's
            interpreter's arguments; ``{path}``, ``{nproc}`` filled in)
            that makes the folder on the machine instead of carrying it.
        tiny (str, optional): ``module:function(root)`` writing tiny data
            of its kind for a dry run (None: a dry run needs the folder).
        dry_img_scale (tuple[int, int]): ``(w, h)`` of the dry run.
        val_only (tuple[float, int], optional): As a ``transfer_root``,
            only the val photos of its seeded split are tested
            (``val_fraction``, ``seed`` as the configs set them): it
            travels as ``{name}_val``, every XML and those photos.
    """
    name: str
    dry_img_scale: Tuple[int, int]
    make: Optional[List[str]] = None
    tiny: Optional[str] = None
    val_only: Optional[Tuple[float, int]] = None


def data_folder(root: str) -> str:
    """The folder name of a data root (``data/dawn_fog`` -> ``dawn_fog``):
    its entry in ``device_data``, its folder under ``run_all.py --data``."""
    return osp.basename(osp.normpath(root))


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _strings(value) -> bool:
    return isinstance(value, (list, tuple)) and all(
        isinstance(v, str) and v for v in value)


def only_keys(where: str, value, keys: Tuple[str, ...], it: str) -> dict:
    """``value``, checked to be a dict of ``keys`` (``it``: what a
    message calls its owner)."""
    if not isinstance(value, dict):
        raise ValueError(f'{where} must be dict(...) with keys from '
                         f'{list(keys)}, got {value!r}')
    bad = sorted(set(value) - set(keys))
    if bad:
        raise ValueError(f'{where}: unknown keys {bad}; {it} has '
                         f'{list(keys)}')
    return value


def _writer(where: str, key: str, value) -> str:
    if not isinstance(value, str) or not WRITER.match(value):
        raise ValueError(f'{where}: {key} must be a writer '
                         f"'module:function', got {value!r}")
    return value


def device_data(path: str, spec: dict, presets: dict
                ) -> Dict[str, DeviceData]:
    """The presets file's ``device_data`` (``spec``, read from ``path``):
    what the lent GPU machine does with each data folder, checked against
    the ``presets`` (name -> Preset).

    Raises:
        ValueError: A malformed entry (its key and what it must be), or a
            preset whose data or transfer folder has no entry.
    """
    out = {}
    for name, entry in spec.items():
        where = f'{path}: device_data {name!r}'
        only_keys(where, entry, DEVICE_DATA_KEYS, 'an entry')
        make = entry.get('make')
        if make is not None and not (_strings(make) and make):
            raise ValueError(f"{where}: make must be the interpreter's "
                             f'arguments (strings), got {make!r}')
        tiny = entry.get('tiny')
        if tiny is not None:
            _writer(where, 'tiny', tiny)
        scale = entry.get('dry_img_scale')
        if not (isinstance(scale, (list, tuple)) and len(scale) == 2 and
                all(_is_int(v) and v > 0 for v in scale)):
            raise ValueError(f'{where}: dry_img_scale must be (w, h) in '
                             f'pixels, got {scale!r}')
        val = entry.get('val_only')
        if val is not None and not (
                isinstance(val, (list, tuple)) and len(val) == 2
                and isinstance(val[0], float) and 0 < val[0] < 1
                and _is_int(val[1])):
            raise ValueError(f'{where}: val_only must be (val_fraction, '
                             f'seed) of the seeded split, got {val!r}')
        out[name] = DeviceData(
            name=name, dry_img_scale=tuple(scale),
            make=list(make) if make is not None else None, tiny=tiny,
            val_only=tuple(val) if val is not None else None)
    for preset_name, preset in presets.items():
        for root in (preset.data_root, preset.transfer_root):
            if root is not None and data_folder(root) not in out:
                raise ValueError(
                    f'{path}: preset {preset_name!r}: its folder '
                    f'{data_folder(root)!r} ({root}) has no device_data '
                    'entry')
    return out


def device_spec(path: str, value, recipes: list, preset: str,
                presets: dict) -> DeviceSpec:
    """A set file's ``device`` (None: every default), checked."""
    where = f'{path}: device'
    value = only_keys(where, {} if value is None else value, DEVICE_KEYS,
                      'it')
    on = value.get('preset', preset)
    if on not in presets:
        raise ValueError(f'{where}: unknown preset {on!r}; the presets: '
                         f'{sorted(presets)}')
    rows = {r.name: r for r in recipes}
    if 'dry_row' not in value:
        # the first row that trains (a row tests no other's weights)
        row = next((r.name for r in recipes if not r.test_only and
                    r.weights_of is None), recipes[0].name)
    else:
        row = value['dry_row']
        if row is not None and row not in rows:
            raise ValueError(f'{where}: dry_row {row!r} is no row of the '
                             f'set; its rows: {list(rows)}')
        if row is not None and rows[row].weights_of is not None:
            raise ValueError(
                f'{where}: dry_row {row!r} tests the weights of '
                f'{rows[row].weights_of!r}: the dry run trains one row '
                'alone')
    seeds = value.get('dry_seeds', [0])
    if not (isinstance(seeds, (list, tuple)) and seeds and
            all(_is_int(s) and s >= 0 for s in seeds) and
            len(set(seeds)) == len(seeds)):
        raise ValueError(f'{where}: dry_seeds must be distinct seeds '
                         f'(ints >= 0), got {seeds!r}')
    needs = value.get('needs', [])
    if not _strings(needs) or any(osp.isabs(n) for n in needs):
        raise ValueError(f'{where}: needs must be paths relative to the '
                         f'repository, got {needs!r}')
    weights = value.get('tiny_weights')
    if weights is not None:
        _writer(where, 'tiny_weights', weights)
    return DeviceSpec(preset=on, dry_row=row, dry_seeds=list(seeds),
                      needs=list(needs), tiny_weights=weights)
