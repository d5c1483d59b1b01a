"""Experiment sets as data: one declarative file per set under
``configs/experiments/`` (an MMEngine config), read by the comparison
harness and by the GPU script alike.

A set file names its recipes (each an MMDet config under ``configs/``, or
``../projects/...``), the preset it runs under by default (data root and
budget, from ``configs/experiments/_base_/presets.py``), the columns it
reports, and, where it has them, a second test set, its in-domain ceiling
(another set's record, never retrained) and the rows that train exactly as
another set's::

    # what the set asks, in a comment
    preset = 'realfog_pretrained'
    columns = ['box AP', 'box AP50']
    recipes = [
        dict(name='Cascade R-CNN', config='pretrained/cascade-rcnn_....py'),
        # tests another row's weights under its own test settings
        dict(name='DCP + ...', config='...', weights_of='Cascade R-CNN'),
        # trains nothing: tests the weights its config loads (load_from)
        dict(name='zero-shot', config='...', test_only=True),
        # its own budget over the set's: twice the set's iterations (any
        # other key: a Budget field, set as it is)
        dict(name='..., 24 epochs', config='...',
             budget=dict(iters_scale=2)),
        # its input size is part of the model: its config's Resize sizes
        # stay, the preset's img_scale does not apply
        dict(name='edge, 320 px', config='...', keep_img_scale=True),
    ]
    # every run also tested on a VOC real-fog folder's val split, under
    # this condition (--transfer-root, or the preset's, moves it)
    transfer_test = dict(condition='real fog', data_root='data/dawn_fog/',
                         split='val', val_fraction=0.3, split_seed=0)

Row names are the keys of the runs (``{work_dir}/{slug(name)}/seed{s}``):
rows are only ever appended or renamed together with their runs.

The sets are read once, on import (:data:`SETS` and the tables drawn from
it); :func:`resolve_recipes` gives a comparison its recipes, from a set
and / or config files, and :func:`row_budget` a row its own budget.

How the lent GPU machine runs the set (``tools/device/run_all.py``), where
it differs from the defaults, is the optional ``device`` key::

    device = dict(
        # the preset it runs under there (default: the set's)
        preset='realfog_200it',
        # the one row its dry run trains (default: the first row that
        # trains; None: every row), for these seeds (default [0])
        dry_row='YOLOX-Tiny', dry_seeds=[0, 1],
        # files its rows read, relative to the repository (carried)
        needs=['work_dirs/dehaze/.../iter_200.pth'],
        # ``module:function(folder)`` writing stand-ins of the pretrained
        # files it loads, for a dry run without --pretrained
        tiny_weights='cbnet_tools.synthetic.yolox_checkpoints:'
        'tiny_yolox_nano')

What the machine does with a preset's data (make it there, write tiny
data for a dry run, carry only the val photos) is the presets file's
``device_data``, by data folder (:func:`load_device_data`).
"""
import os.path as osp
from dataclasses import dataclass, field, replace
from typing import Dict, List, Optional, Sequence, Tuple

from mmengine.config import Config

from .config_edits import Budget, configs_root
from .metric_keys import columns as metric_columns
from .set_conditions import conditions_by_folder, transfer_test
from .set_device import (DeviceData, DeviceSpec, data_folder,  # noqa: F401
                         device_data, device_spec, only_keys)

#: The folder of the set files, under the configs root.
EXPERIMENTS = 'experiments'
#: The presets file, under :data:`EXPERIMENTS`.
PRESETS_FILE = osp.join('_base_', 'presets.py')
#: The keys a row may have.
ROW_KEYS = ('name', 'config', 'weights_of', 'test_only', 'budget',
            'keep_img_scale')
#: The keys a set file may have.
SET_KEYS = ('preset', 'columns', 'recipes', 'transfer_test', 'ceiling',
            'trained_as', 'device')


@dataclass
class Preset:
    """A data root and the budget that goes with it (``--preset``).

    Attributes:
        data_root (str): Where the data of the same name is.
        iters (int): Training iterations per run.
        batch_size (int): Images per iteration.
        warmup_iters (int): Linear warm-up iterations.
        img_scale (tuple[int, int], optional): ``(w, h)`` of every Resize
            (None: each config's own).
        transfer_root (str, optional): The real-fog folder of the set's
            second test set, in place of its ``transfer_test``'s
            ``data_root`` (None: the set file's).
    """
    data_root: str
    iters: int
    batch_size: int
    warmup_iters: int
    img_scale: Optional[Tuple[int, int]] = None
    transfer_root: Optional[str] = None

    def describe(self) -> str:
        size = 'config sizes' if self.img_scale is None else \
            'x'.join(str(v) for v in self.img_scale[::-1])
        tested = '' if self.transfer_root is None else \
            f', also tested on {self.transfer_root}'
        return (f'{self.data_root}, {self.iters} iters x '
                f'{self.batch_size} images, {size}{tested}')


@dataclass
class Recipe:
    """One row of a set.

    Attributes:
        name (str): The row's name (its runs' key).
        config (str): The config, relative to the configs root.
        weights_of (str, optional): An earlier row whose weights this row
            tests (per seed) under its own test settings; trains nothing.
        test_only (bool): Train nothing; test the weights the config
            loads (``load_from``), e.g. a pretrained detector zero-shot.
        budget (dict): This row's budget over the set's:
            ``iters_scale`` multiplies the set's iterations (``2``: twice
            the epochs), other keys are ``Budget`` fields.
        keep_img_scale (bool): Its input size is part of the model (the
            edge model): every ``Resize`` keeps its config's size, the
            budget's ``img_scale`` does not apply.
    """
    name: str
    config: str
    weights_of: Optional[str] = None
    test_only: bool = False
    budget: Dict = field(default_factory=dict)
    keep_img_scale: bool = False


@dataclass
class ExperimentSet:
    """A set file, read.

    Attributes:
        name (str): The set (its file's name).
        file (str): The set file.
        recipes (list[Recipe]): Its rows, in order.
        preset (str): The preset it runs under by default.
        columns (tuple, optional): ``(name, metric key, scale)`` of the
            columns it reports first (None: the detection columns).
        transfer_test (dict, optional): Its second test set, which every
            run is also tested on (``condition``, the VOC folder
            ``data_root`` and its split's arguments:
            :func:`cbnet_lab.config_edits.transfer_cfg`).
        ceiling (dict, optional): Its in-domain ceiling, from another
            set's record (``set``, ``condition``, ``what``, ``rows``).
        trained_as (dict, optional): Rows that train exactly as rows of
            another set (``set``, ``rows``: this set's name -> theirs).
        device (DeviceSpec, optional): How the lent GPU machine runs it.
    """
    name: str
    file: str
    recipes: List[Recipe]
    preset: str = 'demo'
    columns: Optional[tuple] = None
    transfer_test: Optional[dict] = None
    ceiling: Optional[dict] = None
    trained_as: Optional[dict] = None
    device: Optional[DeviceSpec] = None

    def recipe(self, name: str) -> Recipe:
        for recipe in self.recipes:
            if recipe.name == name:
                return recipe
        raise KeyError(f'set {self.name!r} has no row {name!r}; its rows: '
                       f'{[r.name for r in self.recipes]}')


def experiments_dir() -> str:
    """``configs/experiments`` of the source tree or installed wheel."""
    return osp.join(configs_root(), EXPERIMENTS)


def set_files() -> Dict[str, str]:
    """Set name -> its file: every ``*.py`` directly under
    :func:`experiments_dir` (not ``_base_/``)."""
    import glob
    folder = experiments_dir()
    return {osp.splitext(osp.basename(p))[0]: p
            for p in sorted(glob.glob(osp.join(folder, '*.py')))}


def _plain(cfg: Config) -> dict:
    """A set file's keys (MMEngine adds none to a base-less config)."""
    return {k: v for k, v in cfg.to_dict().items()}


def _presets_file(key: str, form: str) -> Tuple[str, dict]:
    """The presets file and its ``key``, a dict of ``form``'s items."""
    path = osp.join(experiments_dir(), PRESETS_FILE)
    value = _plain(Config.fromfile(path)).get(key)
    if not isinstance(value, dict) or not value:
        raise ValueError(f'{path}: no {key} = dict({form}, ...)')
    return path, value


def load_presets() -> Dict[str, Preset]:
    """Every preset of ``configs/experiments/_base_/presets.py``."""
    path, presets = _presets_file('presets', 'NAME=dict(...)')
    out = {}
    for name, spec in presets.items():
        spec = dict(spec)
        for key in ('img_scale', ):
            if spec.get(key) is not None:
                spec[key] = tuple(spec[key])
        try:
            out[name] = Preset(**spec)
        except TypeError as err:
            raise ValueError(f'{path}: preset {name!r}: {err}') from None
    return out


def load_device_data() -> Dict[str, DeviceData]:
    """The presets file's ``device_data``: what the lent GPU machine does
    with each data folder (``tools/device/run_all.py``;
    :func:`cbnet_lab.set_device.device_data`).

    Raises:
        ValueError: A malformed entry (its key and what it must be), or a
            preset whose data or transfer folder has no entry.
    """
    path, spec = _presets_file('device_data', 'FOLDER=dict(...)')
    return device_data(path, spec, load_presets())


def load_test_conditions() -> Dict[str, str]:
    """The presets file's ``test_conditions``: a real-data folder's name ->
    the name its test split is reported under
    (:func:`cbnet_lab.set_conditions.conditions_by_folder`)."""
    path, spec = _presets_file('test_conditions', "FOLDER='NAME'")
    return conditions_by_folder(path, spec)


def load_set(name: str, path: Optional[str] = None) -> ExperimentSet:
    """Read the set file of ``name`` (or ``path``).

    Raises:
        KeyError: No such set.
        ValueError: A malformed file: an unknown key, a row without a name
            or config, a name given twice, a ``weights_of`` that names no
            earlier row, a ``keep_img_scale`` that is not True or False,
            an unknown preset or column, a malformed ``transfer_test`` or
            ``device``.
    """
    if path is None:
        files = set_files()
        if name not in files:
            raise KeyError(f'unknown recipe set {name!r}; the sets '
                           f'({experiments_dir()}): {sorted(files)}')
        path = files[name]
    spec = only_keys(path, _plain(Config.fromfile(path)), SET_KEYS,
                     'a set file')
    rows = spec.get('recipes')
    if not isinstance(rows, (list, tuple)) or not rows:
        raise ValueError(f'{path}: recipes = [dict(name=..., config=...), '
                         '...] is missing or empty')
    recipes, seen = [], []
    for i, row in enumerate(rows):
        if not isinstance(row, dict) or not row.get('name') or \
                not row.get('config'):
            raise ValueError(f'{path}: recipe {i} needs a name and a '
                             f'config, got {row!r}')
        only_keys(f'{path}: recipe {row["name"]!r}', row, ROW_KEYS, 'a row')
        if row['name'] in seen:
            raise ValueError(f'{path}: recipe name {row["name"]!r} given '
                             'twice (names key the runs)')
        of = row.get('weights_of')
        if of is not None and of not in seen:
            raise ValueError(f'{path}: recipe {row["name"]!r} tests the '
                             f'weights of {of!r}, which is no earlier row')
        if not isinstance(row.get('keep_img_scale', False), bool):
            raise ValueError(f'{path}: recipe {row["name"]!r}: '
                             'keep_img_scale must be True or False, got '
                             f'{row["keep_img_scale"]!r}')
        seen.append(row['name'])
        budget = dict(row.get('budget') or {})
        recipes.append(Recipe(**dict(row, budget=budget)))
    preset = spec.get('preset') or 'demo'
    presets = load_presets()
    if preset not in presets:
        raise ValueError(f'{path}: unknown preset {preset!r}; the presets: '
                         f'{sorted(presets)}')
    columns = spec.get('columns')
    if columns is not None:
        try:
            columns = metric_columns(*columns)
        except KeyError as err:
            raise ValueError(f'{path}: unknown column {err}') from None
    return ExperimentSet(
        name=name, file=path, recipes=recipes, preset=preset,
        columns=columns,
        transfer_test=transfer_test(path, spec.get('transfer_test')),
        ceiling=spec.get('ceiling'),
        trained_as=spec.get('trained_as'),
        device=device_spec(path, spec.get('device'), recipes, preset,
                           presets))


def load_sets() -> Dict[str, ExperimentSet]:
    """Every set of :func:`set_files`, read."""
    return {name: load_set(name, path) for name, path in set_files().items()}


#: The sets (``configs/experiments/*.py``), read once: set name -> the
#: set.
SETS = load_sets()

#: Set name -> its rows as (recipe name, config path relative to the
#: configs root; the peer baseline's configs are under
#: ``../projects/peer_dehaze/configs``, which the wheel carries beside
#: ``configs`` in ``cbnet_mmdet/.mim``).
RECIPE_SETS: Dict[str, List[Tuple[str, str]]] = {
    name: [(r.name, r.config) for r in s.recipes] for name, s in SETS.items()
}

#: Sets that report other columns than :data:`DETECTION_COLUMNS` (their
#: files' ``columns``): real fog on a pretrained trunk adds COCO's AP per
#: object size (DAWN's vehicles range from a few pixels to half the photo).
SET_COLUMNS = {name: s.columns for name, s in SETS.items()
               if s.columns is not None}

#: The in-domain ceiling of a set (its file's ``ceiling``), tabulated
#: from another set's record and never retrained: the record's set, the
#: condition read from it, which of its recipes stands beside which of
#: this set's (by the prefix of this set's row names), and what it is.
SET_CEILINGS = {name: s.ceiling for name, s in SETS.items()
                if s.ceiling is not None}

#: Rows of a set that train exactly as rows of another set (its file's
#: ``trained_as``; their configs add test settings only, :func:`trained_as`
#: checks it): with ``weights_from`` (that set's work dir) their finished
#: runs are tested instead of trained again.
SET_TRAINED_AS = {name: s.trained_as for name, s in SETS.items()
                  if s.trained_as is not None}

#: The presets (``--preset``: ``configs/experiments/_base_/presets.py``).
PRESETS: Dict[str, Preset] = load_presets()

#: The real-data folders (the presets file's ``test_conditions``): the
#: folder's name -> the name its test split is reported under.
TEST_CONDITIONS: Dict[str, str] = load_test_conditions()

#: The preset a set runs with when ``--preset`` is not given (its file's
#: ``preset``; ``demo`` where it names none).
SET_PRESETS = {name: s.preset for name, s in SETS.items()
               if s.preset != 'demo'}


def data_condition(data_root: Optional[str]) -> Optional[str]:
    """The name the test split of ``data_root`` is reported under: its
    folder's entry in :data:`TEST_CONDITIONS` (real data: tested as it
    is, no foggy betas), None for Cityscapes-layout data (clear val,
    then foggy val per beta). A recipe's condition is its config's
    ``data_root``'s, wherever ``--data-root`` moves its data."""
    return None if not data_root else \
        TEST_CONDITIONS.get(data_folder(data_root))


def resolve_recipes(set_name: Optional[str] = None,
                    configs: Sequence[str] = (),
                    only: Optional[Sequence[str]] = None
                    ) -> List[Tuple[str, str]]:
    """Recipes of a built-in set and/or ``NAME=PATH`` (or ``PATH``) items.

    Args:
        set_name (str, optional): A key of :data:`RECIPE_SETS`.
        configs (Sequence[str]): Extra recipes, ``NAME=PATH`` or ``PATH``
            (named after the file).
        only (Sequence[str], optional): Keep only these recipe names (in
            the set's order), e.g. one table of a set first.

    Returns:
        list[tuple[str, str]]: (name, absolute config path), in order.
    """
    recipes = []
    if set_name is not None:
        if set_name not in RECIPE_SETS:
            raise ValueError(f'unknown recipe set {set_name!r}; built-in '
                             f'sets: {sorted(RECIPE_SETS)}')
        root = configs_root()
        recipes += [(name, osp.join(root, path))
                    for name, path in RECIPE_SETS[set_name]]
    for item in configs:
        name, _, path = item.rpartition('=')
        name = name or osp.splitext(osp.basename(path))[0]
        recipes.append((name, osp.abspath(path)))
    if only is not None:
        known = [n for n, _ in recipes]
        unknown = [n for n in only if n not in known]
        if unknown:
            raise ValueError(f'--only: no recipe named {unknown}; the '
                             f'recipes are {known}')
        recipes = [(n, p) for n, p in recipes if n in set(only)]
    if not recipes:
        raise ValueError('no recipes: give a --set or --configs')
    for name, path in recipes:
        if not osp.isfile(path):
            raise FileNotFoundError(f'recipe {name!r}: config {path} not '
                                    'found')
    names = [n for n, _ in recipes]
    if len(set(names)) != len(names):
        raise ValueError(f'recipe names must be unique, got {names}')
    return recipes


def set_rows(set_name: Optional[str],
             recipes: Sequence[Tuple[str, str]]) -> Dict[str, Recipe]:
    """The set file rows of ``recipes`` (those of set ``set_name`` with
    the row's own config; a ``--configs`` recipe has none)."""
    if set_name is None:
        return {}
    root = configs_root()
    rows = {r.name: r for r in SETS[set_name].recipes}
    return {name: rows[name] for name, config in recipes
            if name in rows and osp.realpath(config) ==
            osp.realpath(osp.join(root, rows[name].config))}


def row_budget(budget: Budget, row: Optional[Recipe]) -> Budget:
    """``budget`` with a row's own ``budget`` keys over it: ``iters_scale``
    multiplies the set's iterations (so that ``--iters`` moves every row
    alike: ``iters_scale=2`` trains twice as long as the others), any
    other key is a :class:`Budget` field set as it is."""
    if row is None or not row.budget:
        return budget
    over = dict(row.budget)
    scale = over.pop('iters_scale', None)
    if scale is not None:
        if not isinstance(scale, (int, float)) or scale <= 0:
            raise ValueError(f'recipe {row.name!r}: iters_scale must be a '
                             f'number > 0, got {scale!r}')
        over['iters'] = int(round(budget.iters * scale))
    if over.get('img_scale') is not None:
        over['img_scale'] = tuple(over['img_scale'])
    try:
        return replace(budget, **over)
    except TypeError as err:
        raise ValueError(f'recipe {row.name!r}: budget {row.budget}: '
                         f'{err}') from None
