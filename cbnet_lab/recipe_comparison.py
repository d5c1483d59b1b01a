"""Train recipes on the same data, budget and seeds, and compare them.

The comparison harness behind ``tools/analysis_tools/compare_recipes.py``.
Every recipe is an MMDet config; each is trained with MMEngine's
``Runner`` under one :class:`Budget` (iterations, batch, lr schedule) and
one seed at a time, on the dataset at ``data_root`` (any dataset in the
Cityscapes layout: the generated one or the real Cityscapes /
Foggy Cityscapes), then tested on clear val and on foggy val for each beta
through :func:`cbnet_lab.ap_drop.ap_drop`. Each run writes its
``result.json``; a rerun skips finished runs (resumable). The results are
summarised as mean +- std over seeds per recipe and condition.

Test-time variants. A config that sets ``compare_weights_of = PATH`` (a
config file, relative to the variant's own folder like ``_base_``) is not
trained: each seed tests the weights that the recipe with config ``PATH``
trained for that seed, in the same comparison (listed before it), under
the variant's own test settings (``model.test_cfg``, test pipeline). That
compares, say, test-time proposal counts on the very same weights.

Transfer. A config that also sets ``transfer_test`` (the
``fog_transfer`` set: trained on clear COCO street photos) is tested on
its own test set and then on that real-fog VOC folder (``transfer_root``,
default the config's), two conditions per run and the drop between them
(:func:`cbnet_lab.ap_drop.ap_drop`). A test-time variant's source run must
be finished (its checkpoint on disk): one that another process of the
comparison is still training is waited for, one that is missing (never
trained, or restored from a record without its weights) is an error
naming the file.

Runs trained by another set. Some rows of a set train exactly what a
row of another set trains (:data:`SET_TRAINED_AS`: the fog_transfer set's
clear-only rows are the coco_street set's rows with a second test set;
checked: the two configs must be equal but for their ``transfer_*`` and
``compare_*`` keys). Given ``weights_from`` (the other set's work dir:
same budget, overrides and data), each seed's finished run there is
tested here instead of trained again: its checkpoint is linked into this
run's folder, and the run records its train time and where it was
trained (``trained_in``, ``trained_as``). A run that another process is
still training there is waited for; a seed with no finished run there,
or one without its weights (a restored record), is trained here as usual.

Real data. When the recipes' configs set ``test_condition = NAME`` (the
real-fog configs of ``configs/realfog/``, set ``realfog``), ``data_root``
is that dataset (a VOC folder) and each run is tested on the config's own
test set under condition ``NAME``, with no foggy betas
(:func:`cbnet_lab.ap_drop.ap_drop`); every recipe of a
comparison must then name the same condition.
"""
import copy
import json
import math
import os
import os.path as osp
import platform
import re
import shutil
import time
from dataclasses import asdict, replace
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
from mmengine.device import get_device

from cbnet_tools.markdown import markdown_table
from cbnet_tools.pretrained import require_pretrained

from .ap_drop import ap_drop
from .config_edits import (Budget, ap_drop_cfgs, budget_cfg, checkpoint_iter,
                           configs_root, read_config, resume_file,
                           test_condition, transfer_test)
from .report import machine_line, plot, to_markdown
from .metric_keys import columns as metric_columns
from .sets import Preset, Recipe, load_presets, load_sets

#: The sets (``configs/experiments/*.py``, :mod:`cbnet_lab.sets`), read
#: once: set name -> the set.
SETS = load_sets()
#: Set name -> its rows as (recipe name, config path relative to the
#: configs root; the peer baseline's configs are under
#: ``../projects/peer_dehaze/configs``, which the wheel carries beside
#: ``configs`` in ``cbnet_mmdet/.mim``).
RECIPE_SETS: Dict[str, List[Tuple[str, str]]] = {
    name: [(r.name, r.config) for r in s.recipes] for name, s in SETS.items()
}

#: Reported columns: (name, metric key, scale to percent). Detection sets
#: report COCO AP (``CocoMetric``) and mIoU (``CBNetInstanceMIoUMetric``);
#: RPN sets the average recall at 100/300/1000 proposals.
DETECTION_COLUMNS = metric_columns('box AP', 'box AP50', 'mask AP',
                                   'mask AP50', 'mIoU')
PROPOSAL_COLUMNS = metric_columns('AR@100', 'AR@300', 'AR@1000')
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
#: The preset a set runs with when ``--preset`` is not given (its file's
#: ``preset``; ``demo`` where it names none).
SET_PRESETS = {name: s.preset for name, s in SETS.items()
               if s.preset != 'demo'}


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


def slug(name: str) -> str:
    """A folder name for a recipe name (``+shape +edge`` -> ``shape_edge``)."""
    return re.sub(r'[^A-Za-z0-9.]+', '_', name).strip('_') or 'recipe'


def _save_untrained(runner, path: str) -> None:
    """Initialise the runner's model and save it as a checkpoint."""
    import torch
    from mmengine.runner.checkpoint import save_checkpoint, weights_to_cpu
    torch.manual_seed(runner.seed)
    runner.model.init_weights()
    save_checkpoint(
        dict(state_dict=weights_to_cpu(runner.model.state_dict()),
             meta=dict(untrained=True)), path)


def with_front_end(cfg, checkpoint: str, run_dir: str) -> Tuple[str, int]:
    """The weights a test-only row tests: ``checkpoint``, or a copy of it
    with the weights of a front end that the row puts in front of it.

    A test-only row (``compare_weights_of``) may put a part with weights
    in front of another row's detector: a learned dehazer in its data
    preprocessor, whose own ``init_weights`` loads it from its own file
    (``dehaze_checkpoint``). The detector's checkpoint has none of those
    tensors, and ``Runner.test`` does not initialise the model: tested as
    it is, the checkpoint-fit check refuses it (rightly: the front end
    would run with random weights). The data preprocessor alone is built
    and initialised, and its tensors that the checkpoint lacks (under
    ``data_preprocessor.``) are added to a copy in ``run_dir``; every
    other tensor still comes from ``checkpoint`` and is still checked. A
    front end without weights (the dark channel prior) tests
    ``checkpoint`` itself, unread here.

    Args:
        cfg (Config): The test-only row's config.
        checkpoint (str): The other row's checkpoint.
        run_dir (str): The test-only run's folder.

    Returns:
        tuple[str, int]: The checkpoint to test and how many tensors were
        added (0: ``checkpoint`` itself).
    """
    from mmdet.registry import MODELS
    from mmengine.registry import init_default_scope
    from mmengine.runner.checkpoint import save_checkpoint
    from mmengine.utils import import_modules_from_strings

    from cbnet_mmdet.utils.checkpoint.files import read_checkpoint
    if cfg.get('custom_imports'):
        import_modules_from_strings(**cfg.custom_imports)
    init_default_scope(cfg.get('default_scope', 'mmdet'))
    front = MODELS.build(copy.deepcopy(cfg.model.data_preprocessor))
    names = list(front.state_dict())
    if not names:
        return checkpoint, 0
    ckpt = read_checkpoint(checkpoint)
    state = ckpt.get('state_dict', ckpt)
    missing = [k for k in names if f'data_preprocessor.{k}' not in state]
    if not missing:
        return checkpoint, 0
    front.init_weights()
    weights = front.state_dict()
    state = dict(state, **{f'data_preprocessor.{k}': weights[k].cpu()
                           for k in missing})
    meta = dict(ckpt.get('meta') or {}, front_end_added=len(missing))
    out = osp.join(run_dir, 'front_end_' + osp.basename(checkpoint))
    os.makedirs(run_dir, exist_ok=True)
    save_checkpoint(dict(state_dict=state, meta=meta), out)
    return out, len(missing)


def result_file(out_dir: str, name: str, seed: int) -> str:
    """Where :func:`run_recipe` keeps the result of one recipe and seed."""
    return osp.join(out_dir, slug(name), f'seed{seed}', 'result.json')


def resume_iter(work_dir: str) -> Optional[int]:
    """The iteration of :func:`resume_file`, None to start from 0."""
    path = resume_file(work_dir)
    return None if path is None else checkpoint_iter(path)


def checkpoint_file(out_dir: str, name: str, seed: int,
                    budget: Budget) -> str:
    """The weights that :func:`run_recipe` tests for one recipe and seed."""
    last = f'iter_{budget.iters}.pth' if budget.iters > 0 else \
        'untrained.pth'
    return osp.join(osp.dirname(result_file(out_dir, name, seed)), last)


def weights_sources(
        recipes: Sequence[Tuple[str, str]],
        rows: Optional[Dict[str, Recipe]] = None
) -> Dict[str, Optional[str]]:
    """Which recipe's weights each recipe tests (None: its own, trained).

    A set file's row with ``weights_of = NAME`` names an earlier row; a
    config with ``compare_weights_of = PATH`` names the config of an
    earlier recipe of ``recipes``; ``PATH`` is relative to the config's
    folder (or absolute).

    Args:
        recipes (Sequence[tuple[str, str]]): (name, config path), in order.
        rows (dict, optional): Recipe name -> its set file row
            (:func:`set_rows`).

    Returns:
        dict: recipe name -> name of the recipe whose weights it tests.

    Raises:
        ValueError: ``PATH`` is not the config of an earlier recipe, or that
            recipe is itself a test-time variant.
    """
    sources, seen = {}, {}
    rows = rows or {}
    for name, config in recipes:
        target = read_config(config).get('compare_weights_of')
        row = rows.get(name)
        if row is not None and row.weights_of is not None:
            if sources.get(row.weights_of, 'missing') is not None:
                raise ValueError(
                    f'recipe {name!r} tests the weights of '
                    f'{row.weights_of!r}, which is not an earlier recipe of '
                    'this comparison that trains (give it too, before '
                    f'{name!r})')
            sources[name] = row.weights_of
        elif target is None:
            sources[name] = None
        else:
            path = osp.realpath(
                osp.join(osp.dirname(osp.abspath(config)), target))
            source = seen.get(path)
            if source is None or sources[source] is not None:
                raise ValueError(
                    f'recipe {name!r} tests the weights of {path} '
                    '(compare_weights_of), but no earlier recipe of the '
                    'comparison trains that config: list it before '
                    f'{name!r}')
            sources[name] = source
        seen.setdefault(osp.realpath(config), name)
    return sources


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


def trained_as(set_name: Optional[str],
               recipes: Sequence[Tuple[str, str]]) -> Dict[str, str]:
    """Which of ``recipes`` train exactly as a row of another set.

    Args:
        set_name (str, optional): The comparison's set
            (:data:`SET_TRAINED_AS`).
        recipes (Sequence[tuple[str, str]]): (name, config path).

    Returns:
        dict: recipe name -> the other set's row name, for the recipes of
        ``recipes`` that the set names.

    Raises:
        ValueError: The set has no such rows, or a row's config differs
            from the other row's in more than its ``transfer_*`` /
            ``compare_*`` keys: training one would not be training the
            other.
    """
    spec = SET_TRAINED_AS.get(set_name)
    if spec is None:
        raise ValueError(
            f'no row of the set {set_name!r} trains as another set\'s '
            '(--weights-from is for ' + ', '.join(sorted(SET_TRAINED_AS)) +
            ')')

    def training_keys(config: str) -> dict:
        return {k: v for k, v in read_config(config).to_dict().items()
                if not k.startswith(('transfer_', 'compare_'))}

    theirs = dict(resolve_recipes(spec['set']))
    found = {}
    for name, config in recipes:
        other = spec['rows'].get(name)
        if other is None:
            continue
        mine, its = training_keys(config), training_keys(theirs[other])
        differ = sorted(k for k in set(mine) | set(its)
                        if mine.get(k) != its.get(k))
        if differ:
            raise ValueError(
                f'recipe {name!r} should train as the {spec["set"]} set\'s '
                f'{other!r}, but their configs differ in {differ} (only '
                'transfer_* and compare_* keys may)')
        found[name] = other
    return found


def check_weights_from(weights_from: str,
                       data_root: Optional[str] = None) -> None:
    """Check, once, the other set's work dir that ``find_trained`` reads.

    Args:
        weights_from (str): The other comparison's work dir.
        data_root (str, optional): This comparison's data; where the other
            work dir has a ``compare.json``, its data root must match.

    Raises:
        FileNotFoundError: ``weights_from`` is not a folder.
        ValueError: It was trained on other data.
    """
    if not osp.isdir(weights_from):
        raise FileNotFoundError(
            f'--weights-from {weights_from}: no such folder (the work dir '
            'of the comparison that trained the rows)')
    record = osp.join(weights_from, 'compare.json')
    if data_root is not None and osp.isfile(record):
        with open(record) as f:
            theirs = json.load(f).get('data_root')
        if theirs is not None and \
                osp.realpath(theirs) != osp.realpath(data_root):
            raise ValueError(
                f'{weights_from} was trained on {theirs}, this comparison '
                f'runs on {data_root}: its weights are not this data\'s')


def find_trained(weights_from: str, name: str, seed: int, budget: Budget,
                 cfg_options: Optional[dict] = None
                 ) -> Tuple[Optional[str], bool]:
    """A run of recipe ``name`` and ``seed`` in another set's work dir
    (checked by :func:`check_weights_from`); reads only.

    Args:
        weights_from (str): The other comparison's work dir.
        name (str): The recipe's name there.
        seed (int): The seed.
        budget (Budget): This comparison's budget; the run's must match.
        cfg_options (dict, optional): This comparison's overrides; the
            run's must match.

    Returns:
        tuple: (the run's ``result.json`` when it is finished with its
        weights on disk, else None; whether another live process is
        training it now).

    Raises:
        ValueError: The run there was trained under another budget or
            overrides.
    """
    path = result_file(weights_from, name, seed)
    if not osp.isfile(path):
        return None, held_elsewhere(weights_from, name, seed)
    read_result(path, budget, cfg_options)  # the same budget and overrides
    weights = checkpoint_file(weights_from, name, seed, budget)
    return (path if osp.isfile(weights) else None), False


def _options(cfg_options: Optional[dict]) -> dict:
    """``cfg_options`` as a run's record holds it (JSON types; {} for
    none)."""
    return json.loads(json.dumps(cfg_options or {}))


def read_result(path: str, budget: Budget,
                cfg_options: Optional[dict] = None) -> dict:
    """A finished run's ``result.json``, checked against ``budget`` and
    ``cfg_options``.

    Args:
        path (str): The run's ``result.json``.
        budget (Budget): The budget of the comparison that reads it.
        cfg_options (dict, optional): The comparison's ``--cfg-options``;
            a run records those it was trained with (none: no key).

    Returns:
        dict: The run's record.

    Raises:
        ValueError: The run was trained under another budget (another
            ``--iters``, batch, image size...) or other config overrides:
            its numbers would be mixed into this comparison's tables
            silently.
    """
    with open(path) as f:
        result = json.load(f)
    want = json.loads(json.dumps(asdict(budget)))
    have = dict(want, **result.get('budget', {}))
    if have != want:
        changed = {k: (have[k], want[k]) for k in want if have[k] != want[k]}
        raise ValueError(
            f'{path} was trained under another budget (was, now): {changed}; '
            'give this comparison its own --work-dir')
    had, now = result.get('cfg_options', {}), _options(cfg_options)
    if had != now:
        raise ValueError(
            f'{path} was trained with --cfg-options {had or "(none)"}, this '
            f'comparison gives {now or "(none)"}; give the same options or '
            'its own --work-dir')
    return result


def restore_runs(record_path: str, out_dir: str, budget: Budget) -> int:
    """Write the runs of a saved ``compare.json`` back as ``result.json``.

    A comparison's record (e.g. committed under ``docs/accuracy/``) holds
    every run it finished; restoring them into a fresh ``out_dir`` lets a
    comparison go on on another machine or in another session, training
    only what the record lacks. Runs already in ``out_dir`` are kept.

    Args:
        record_path (str): A ``compare.json``.
        out_dir (str): The comparison's output folder.
        budget (Budget): This comparison's budget; the record's must match.

    Returns:
        int: How many runs were written.

    Raises:
        ValueError: The record's budget is not ``budget``.
    """
    with open(record_path) as f:
        record = json.load(f)
    want = json.loads(json.dumps(asdict(budget)))
    have = dict(want, **record.get('budget', {}))
    if have != want:
        raise ValueError(
            f'{record_path} was made under budget {have}, this comparison '
            f'runs {want}: its runs cannot be mixed in')
    written = 0
    for run in record.get('runs', []):
        path = result_file(out_dir, run['recipe'], run['seed'])
        if osp.isfile(path):
            continue
        os.makedirs(osp.dirname(path), exist_ok=True)
        with open(path, 'w') as f:
            json.dump(run, f, indent=1)
        written += 1
    return written


def run_recipe(name: str, config: str, seed: int, budget: Budget,
               data_root: str, betas: Sequence[float], out_dir: str,
               cfg_options: Optional[dict] = None,
               weights_of: Optional[str] = None,
               transfer_root: Optional[str] = None,
               trained_in: Optional[str] = None,
               test_only: bool = False) -> dict:
    """Train one recipe with one seed and test it on clear and foggy val.

    Finished runs are read back from their ``result.json``. With
    ``weights_of`` nothing is trained: the weights that recipe trained for
    ``seed`` (in ``out_dir``) are tested under this recipe's config.

    Args:
        name (str): Recipe name.
        config (str): Config file.
        seed (int): Seed.
        budget (Budget): Training budget.
        data_root (str): Dataset root.
        betas (Sequence[float]): Fog densities (1/m) to test on.
        out_dir (str): Output folder of the comparison.
        cfg_options (dict, optional): Config overrides.
        weights_of (str, optional): Name of the recipe whose weights to
            test (a test-time variant); None trains this recipe.
        transfer_root (str, optional): The folder of the config's
            ``transfer_test`` set (None: the config's own).
        trained_in (str, optional): The ``result.json`` of a finished run
            that trained this recipe as it is (:func:`find_trained`): its
            checkpoint is linked here and tested, nothing is trained.
        test_only (bool): Train nothing: test the weights the config loads
            (``load_from``: a pretrained detector, zero-shot).

    Returns:
        dict: ``recipe``, ``config``, ``seed``, ``train_time_s`` (None for
        a test-time variant, which also has ``weights_of``, and for a
        test-only row, which has ``test_only`` and ``weights``; the source
        run's with ``trained_in``, then also ``trained_in``: that run's
        folder and ``trained_as``: its recipe), ``metrics`` (per
        condition: ``clear``, ``foggy beta=B``).
    """
    from mmengine.runner import Runner

    path = result_file(out_dir, name, seed)
    run_dir = osp.dirname(path)
    if osp.isfile(path):
        return read_result(path, budget, cfg_options)
    stamp = time.strftime('%Y%m%d_%H%M%S')
    cfg = budget_cfg(config, budget, seed, data_root, run_dir, cfg_options,
                     experiment_name=f'{slug(name)}_seed{seed}_{stamp}')
    extra = {}
    if test_only:
        checkpoint = cfg.get('load_from')
        if not checkpoint:
            raise ValueError(
                f'recipe {name!r} is test-only (it trains nothing), but its '
                f'config {config} loads no weights (load_from)')
        require_pretrained(cfg)  # a known file names its fetch command
        checkpoint = osp.expanduser(checkpoint)
        if not osp.isfile(checkpoint):
            raise FileNotFoundError(
                f'recipe {name!r} tests {checkpoint} (its load_from), which '
                'does not exist')
        weights = checkpoint
        checkpoint, added = with_front_end(cfg, checkpoint, run_dir)
        train_time, extra = None, dict(test_only=True, weights=weights)
        if added:
            extra['front_end_tensors'] = added
    elif weights_of is not None:
        checkpoint = checkpoint_file(out_dir, weights_of, seed, budget)
        if not osp.isfile(checkpoint):
            done = osp.isfile(result_file(out_dir, weights_of, seed))
            why = ('its result.json is there but not its weights (a run '
                   'restored from a record?): train that run again here '
                   '(remove its result.json) or use the work dir that '
                   'holds them') if done else \
                ('that run has not been trained in this work dir: run the '
                 f'comparison with {weights_of!r} (list it before '
                 f'{name!r}) first')
            raise FileNotFoundError(
                f'recipe {name!r} trains nothing: it tests the weights of '
                f'{weights_of!r}, seed {seed}, but {checkpoint} does not '
                f'exist; {why}')
        checkpoint, added = with_front_end(cfg, checkpoint, run_dir)
        train_time, extra = None, dict(weights_of=weights_of)
        if added:  # the source's weights and a front end of its own
            extra['front_end_tensors'] = added
    elif trained_in is not None:
        with open(trained_in) as f:
            source = json.load(f)
        checkpoint = checkpoint_file(out_dir, name, seed, budget)
        if not osp.isfile(checkpoint):
            weights = osp.join(osp.dirname(trained_in),
                               osp.basename(checkpoint))
            os.makedirs(run_dir, exist_ok=True)
            try:  # the same file, not a copy, where the disk allows
                os.link(weights, checkpoint)
            except OSError:
                shutil.copy2(weights, checkpoint)
        train_time = source['train_time_s']
        extra = dict(trained_in=osp.dirname(trained_in),
                     trained_as=source['recipe'])
        extra.update({k: source[k] for k in (
            'resumed_at_iter', 'train_time_extrapolated') if k in source})
    else:
        require_pretrained(cfg)
        resumed = checkpoint_iter(cfg.load_from) \
            if budget.iters > 0 and cfg.resume else None
        runner = Runner.from_cfg(cfg)
        start = time.perf_counter()
        checkpoint = checkpoint_file(out_dir, name, seed, budget)
        if budget.iters > 0:
            runner.train()
        else:
            _save_untrained(runner, checkpoint)
        train_time = time.perf_counter() - start
        del runner
        if resumed is not None:
            # this process trained iterations resumed..iters only: the
            # whole run's time is extrapolated, and the record says so
            done = budget.iters - resumed
            train_time = train_time * budget.iters / done if done else None
            extra = dict(resumed_at_iter=resumed,
                         train_time_extrapolated=True)
    table = ap_drop(ap_drop_cfgs(cfg, checkpoint, osp.join(run_dir, 'test'),
                                 betas, transfer_root=transfer_root))
    result = dict(
        recipe=name, config=config, seed=seed, budget=asdict(budget),
        train_time_s=train_time, metrics=table['metrics'], **extra)
    if cfg_options:
        # what else it was trained with (read_result refuses to mix it)
        result['cfg_options'] = _options(cfg_options)
    os.makedirs(run_dir, exist_ok=True)
    with open(path, 'w') as f:
        json.dump(result, f, indent=1)
    return result


class RunLock:
    """A lock file in a run's folder, held by the process training it.

    ``acquire`` creates ``.lock`` (holding ``host:pid``) atomically. A lock
    left by a process that no longer runs on this host (killed) is stale
    and taken over, so a killed comparison resumes.

    Args:
        run_dir (str): The run's folder (``acquire`` creates it if missing;
            reading the lock writes nothing).
    """

    def __init__(self, run_dir: str):
        self.path = osp.join(run_dir, '.lock')
        self.held = False

    @staticmethod
    def _me() -> str:
        return f'{platform.node()}:{os.getpid()}'

    def holder(self) -> Optional[str]:
        """``host:pid`` of the lock's holder, None when unlocked."""
        try:
            with open(self.path) as f:
                return f.read().strip() or None
        except FileNotFoundError:
            return None

    def held_by_another(self) -> bool:
        """Whether a live process other than this one holds the lock."""
        holder = self.holder()
        return holder is not None and holder != self._me() and \
            not self._stale(holder)

    def _stale(self, holder: Optional[str]) -> bool:
        host, _, pid = (holder or '').rpartition(':')
        if host != platform.node() or not pid.isdigit():
            # another machine's lock (shared folder), or being written
            return False
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            return True
        except PermissionError:
            return False
        return False

    def acquire(self) -> bool:
        """Take the lock; False if a live process holds it."""
        os.makedirs(osp.dirname(self.path), exist_ok=True)
        for _ in range(2):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
            except FileExistsError:
                if not self._stale(self.holder()):
                    return False
                os.remove(self.path)
                continue
            with os.fdopen(fd, 'w') as f:
                f.write(self._me())
            self.held = True
            return True
        return False

    def release(self) -> None:
        """Drop the lock if this object holds it."""
        if self.held and self.holder() == self._me():
            os.remove(self.path)
        self.held = False


def condition_names(betas: Sequence[float],
                    reference: str = 'clear') -> List[str]:
    """Condition keys of :func:`ap_drop`: the reference (clear, or a
    real-data config's ``test_condition``), then each beta."""
    return [reference] + [f'foggy beta={b}' for b in betas]


def reference_condition(recipes: Sequence[Tuple[str, str]]) -> str:
    """The condition every recipe is tested on first: ``'clear'``, or the
    ``test_condition`` all the recipes' configs name (real data).

    Raises:
        ValueError: The recipes name different conditions.
    """
    names = {name: test_condition(read_config(config)) or 'clear'
             for name, config in recipes}
    if len(set(names.values())) > 1:
        raise ValueError(
            'the recipes are tested on different data (test_condition of '
            f'each: {names}); compare recipes of one kind at a time')
    return next(iter(names.values()))


def pick_columns(results: Sequence[dict],
                 candidates: Optional[Sequence[tuple]] = None
                 ) -> Tuple[Tuple[str, str, float]]:
    """The columns whose metric some run reports (detection or proposal).

    A recipe that lacks a column's metric (a box-only detector's mask AP)
    shows ``-`` there, never 0.

    Args:
        results (Sequence[dict]): Outputs of :func:`run_recipe`.
        candidates (Sequence[tuple], optional): Column lists to try in
            order (default: :data:`DETECTION_COLUMNS`, then
            :data:`PROPOSAL_COLUMNS`); a set's own (:data:`SET_COLUMNS`)
            goes first.

    Returns:
        tuple: ``(name, key, scale)`` triples.
    """
    # the reference condition is the first of each run
    keys = set.union(*(set(next(iter(r['metrics'].values())))
                       for r in results))
    if candidates is None:
        candidates = (DETECTION_COLUMNS, PROPOSAL_COLUMNS)
    for columns in candidates:
        chosen = tuple(c for c in columns if c[1] in keys)
        if chosen:
            return chosen
    raise ValueError(f'no known metric in the results: {sorted(keys)}')


def mean_std(values: Sequence[float]) -> Dict[str, float]:
    """Mean and sample standard deviation (0 for one value)."""
    arr = np.asarray(values, dtype=float)
    std = float(arr.std(ddof=1)) if arr.size > 1 else 0.0
    return dict(mean=float(arr.mean()), std=std, n=int(arr.size))


def summarize(results: Sequence[dict], betas: Sequence[float],
              reference: str = 'clear',
              columns: Optional[Sequence[tuple]] = None) -> dict:
    """Mean +- std over seeds per recipe, condition and column.

    A metric below 0 (MMDet's -1: nothing to evaluate) counts as missing.
    Drops are ``clear - foggy`` per seed, then averaged.

    Args:
        results (Sequence[dict]): Outputs of :func:`run_recipe`.
        betas (Sequence[float]): The tested fog densities.
        reference (str): The first condition (clear, or real data's
            ``test_condition``), which the drops are taken from.
        columns (Sequence[tuple], optional): ``(name, key, scale)`` to
            report before the default ones (a set's
            :data:`SET_COLUMNS`).

    Returns:
        dict: ``columns`` (names), ``recipes`` (in order of first
        appearance), and per recipe ``{condition: {column: mean_std}}``
        plus ``'<column> drop'`` entries for the foggy conditions and
        ``train time (s)``.
    """
    columns = pick_columns(
        results, None if columns is None else
        (tuple(columns), DETECTION_COLUMNS, PROPOSAL_COLUMNS))
    conditions = condition_names(betas, reference)
    # a recipe's transfer_test set comes after them (fog_transfer)
    for r in results:
        conditions += [c for c in r['metrics'] if c not in conditions]
    recipes: Dict[str, List[dict]] = {}
    for r in results:
        recipes.setdefault(r['recipe'], []).append(r)

    def value(run, condition, key, scale):
        v = run['metrics'].get(condition, {}).get(key)
        return None if v is None or v < 0 else float(v) * scale

    summary = {}
    for recipe, runs in recipes.items():
        times = [r['train_time_s'] for r in runs
                 if r.get('train_time_s') is not None]
        # a test-time variant trains nothing: '-'
        entry = {'train time (s)': mean_std(times) if times else None}
        for condition in conditions:
            row = {}
            for col, key, scale in columns:
                pairs = [(value(r, reference, key, scale),
                          value(r, condition, key, scale)) for r in runs]
                vals = [v for _, v in pairs if v is not None]
                row[col] = mean_std(vals) if vals else None
                if condition == reference:
                    continue
                drops = [c - v for c, v in pairs
                         if c is not None and v is not None]
                row[f'{col} drop'] = mean_std(drops) if drops else None
            entry[condition] = row
        summary[recipe] = entry
    return dict(columns=[c[0] for c in columns], conditions=conditions,
                recipes=list(recipes), summary=summary)


def check_data(reference: str, data_root: str,
               betas: Sequence[float]) -> None:
    """Clear errors before any training: real data (``reference`` other
    than ``'clear'``) must exist and takes no betas; generated or
    Cityscapes data must have its converted val annotations."""
    if reference != 'clear':
        if not osp.isdir(data_root):
            raise FileNotFoundError(
                f'--data-root {data_root} not found: the recipes test real '
                f'data ({reference!r}); give its folder')
        if betas:
            raise ValueError(
                f'the recipes test real data ({reference!r}): no foggy '
                f'betas apply, got {list(betas)}')
        return
    ann = osp.join(data_root, 'annotations',
                   'instancesonly_filtered_gtFine_val.json')
    if not osp.isfile(ann):
        raise FileNotFoundError(
            f'{ann} not found: --data-root must be a dataset in the '
            'Cityscapes layout with converted annotations (generate one '
            'with `python tools/misc/generate_cityscapes_like.py DIR '
            '--convert`, or convert the real one with '
            '`python tools/dataset_converters/cityscapes.py DIR`)')


def check_transfer(recipes: Sequence[Tuple[str, str]],
                   transfer_root: Optional[str]) -> None:
    """The real-fog folder of the recipes' ``transfer_test`` exists, before
    any training (each config's own ``data_root`` when ``transfer_root``
    is None); ``transfer_root`` without such a recipe is an error."""
    specs = {name: transfer_test(read_config(config))
             for name, config in recipes}
    if transfer_root is not None and not any(specs.values()):
        raise ValueError(
            f'--transfer-root {transfer_root}: no recipe sets transfer_test '
            '(a second test set), so it would not be read')
    for name, spec in specs.items():
        root = transfer_root or (spec or {}).get('data_root')
        if spec is not None and not osp.isdir(root):
            raise FileNotFoundError(
                f'recipe {name!r} is also tested on {spec["condition"]!r}, '
                f'the VOC folder {root}, which does not exist; give it with '
                '--transfer-root')


def held_elsewhere(out_dir: str, name: str, seed: int) -> bool:
    """Whether another live process holds the lock of a run."""
    return RunLock(osp.dirname(result_file(out_dir, name,
                                           seed))).held_by_another()


def ceiling(set_name: Optional[str], record_path: Optional[str],
            columns: Sequence[str]) -> Tuple[Optional[dict], str]:
    """The in-domain ceiling of a set (:data:`SET_CEILINGS`) read from
    another set's saved record, never retrained.

    Args:
        set_name (str, optional): This comparison's set.
        record_path (str, optional): That set's ``compare.json`` (None:
            the table says how to add it).
        columns (Sequence[str]): This comparison's columns.

    Returns:
        tuple: the record's entry (None without ceiling or record) and
        markdown ('' for a set without ceiling).

    Raises:
        ValueError: The record is of another set, or lacks the condition.
    """
    spec = SET_CEILINGS.get(set_name)
    if spec is None:
        if record_path is not None:
            raise ValueError(f'--ceiling: set {set_name!r} has no in-domain '
                             f'ceiling; sets with one: '
                             f'{sorted(SET_CEILINGS)}')
        return None, ''
    head = (f'**in-domain ceiling** ({spec["what"]}: the {spec["set"]} '
            "set's record, not retrained here)")
    if record_path is None:
        return None, (f'{head}: not tabulated; give --ceiling with that '
                      "set's compare.json")
    with open(record_path) as f:
        record = json.load(f)
    if record.get('set') != spec['set']:
        raise ValueError(f'--ceiling {record_path}: a record of set '
                         f'{record.get("set")!r}, not {spec["set"]!r}')
    summary = record['summary']
    if spec['condition'] not in summary.get('conditions', []):
        raise ValueError(f'--ceiling {record_path}: no condition '
                         f'{spec["condition"]!r} in it')
    rows, table = {}, []
    for ours, theirs in spec['rows'].items():
        entry = summary['summary'].get(theirs)
        if entry is None:
            continue
        stats = entry[spec['condition']]
        rows[ours] = dict(recipe=theirs,
                          **{c: stats.get(c) for c in columns})
        table.append([f'{theirs} (beside {ours})'] +
                     [_ceiling_cell(stats.get(c)) for c in columns])
    entry = dict(record=record_path, set=spec['set'],
                 condition=spec['condition'], seeds=record.get('seeds'),
                 date=record.get('date'), budget=record.get('budget'),
                 rows=rows)
    lines = [f'{head}, on {spec["condition"]}, from {record_path} '
             f'(seeds {record.get("seeds")}, {record.get("date")})', '']
    lines += markdown_table(['recipe'] + list(columns), table) if table \
        else ['(none of its recipes is in the record yet)']
    return entry, '\n'.join(lines)


def _ceiling_cell(stat: Optional[dict]) -> str:
    if stat is None:
        return '-'
    if stat.get('n', 1) > 1:
        return f"{stat['mean']:.1f} +- {stat['std']:.1f}"
    return f"{stat['mean']:.1f}"


def check_pretrained(recipes: Sequence[Tuple[str, str]],
                     sources: Dict[str, Optional[str]]) -> None:
    """Every pretrained file the trained recipes load, before the first
    run (not hours later): a missing one is an error naming the command
    that fetches it (:func:`cbnet_tools.pretrained
    .require_pretrained`). Test-time variants load no trunk."""
    for name, config in recipes:
        if sources[name] is None:
            require_pretrained(read_config(config))


def compare(recipes: Sequence[Tuple[str, str]], seeds: Sequence[int],
            budget: Budget, data_root: str, betas: Sequence[float],
            out_dir: str, cfg_options: Optional[dict] = None,
            log: Callable[[str], None] = print,
            set_name: Optional[str] = None, wait_s: float = 30.0,
            train: bool = True, wait: bool = True,
            transfer_root: Optional[str] = None,
            ceiling_record: Optional[str] = None,
            weights_from: Optional[str] = None) -> dict:
    """Run every recipe with every seed, then summarise, tabulate, plot.

    Writes ``compare.json`` (runs, summary, budget, machine, date),
    ``compare.md`` and ``compare.png`` into ``out_dir``.

    Args:
        recipes (Sequence[tuple[str, str]]): (name, config path).
        seeds (Sequence[int]): Seeds; every recipe runs with each.
        budget (Budget): Training budget of every run.
        data_root (str): Dataset root (Cityscapes layout, with
            ``leftImg8bit_foggy`` for the betas; or the real data of
            recipes with a ``test_condition``).
        betas (Sequence[float]): Fog densities to test on (none for real
            data).
        out_dir (str): Output folder.
        cfg_options (dict, optional): Overrides for every config.
        log (callable): Progress printer.
        set_name (str, optional): Name of the built-in set, for the record.
        wait_s (float): Poll interval while the only runs left are being
            trained by other processes of the same comparison.
        train (bool): False tabulates the finished runs in ``out_dir``
            alone (e.g. a record put there with :func:`restore_runs`):
            nothing is trained or tested, no data is read, the runs left
            out are listed (``missing`` in the record, a line under the
            tables) and the record names no machine (``machine`` None:
            the runs say nothing of where they were trained).
        wait (bool): False leaves the runs that other processes are
            training out of this record (``in_progress``, a line under
            the tables) instead of waiting for them, so that a process
            goes on to its next comparison at once; a later run of the
            comparison (or ``--report-only``) tabulates them all.
        transfer_root (str, optional): The real-fog folder of the recipes'
            ``transfer_test`` (None: each config's own); in the record
            when given.
        ceiling_record (str, optional): The ``compare.json`` of the set
            that is this set's in-domain ceiling (:data:`SET_CEILINGS`),
            tabulated under the results (``ceiling`` in the record).
        weights_from (str, optional): The work dir of the set whose rows
            some of this set's rows train as (:data:`SET_TRAINED_AS`):
            its finished runs are tested instead of trained
            (:func:`find_trained`); in the record when given.

    Several processes may run the same comparison (same ``out_dir``) at
    once, e.g. one per core with one thread each: each run is locked by
    the process training it (:class:`RunLock`), the others take the next
    run and, at the end, wait for the locked ones and read their results.

    Returns:
        dict: What ``compare.json`` holds.
    """
    reference = reference_condition(recipes)
    rows = set_rows(set_name, recipes)
    sources = weights_sources(recipes, rows)
    # rows that train nothing and test the weights their config loads
    fixed = {n for n, row in rows.items() if row.test_only}
    budgets = {n: row_budget(budget, rows.get(n)) for n, _ in recipes}
    # a tabulation (train=False) reads the runs here only
    trained_elsewhere = trained_as(set_name, recipes) \
        if weights_from and train else {}
    if trained_elsewhere:
        check_weights_from(weights_from, data_root)

    def trained_there(name: str, seed: int) -> Tuple[Optional[str], bool]:
        if name not in trained_elsewhere:
            return None, False
        return find_trained(weights_from, trained_elsewhere[name], seed,
                            budgets[name], cfg_options)

    if train:  # a tabulation reads no data
        check_data(reference, data_root, betas)
        check_transfer(recipes, transfer_root)
        check_pretrained(recipes, sources)
    os.makedirs(out_dir, exist_ok=True)
    # seed-major: a comparison cut short still has every recipe at the
    # seeds it finished
    jobs = [(name, cfg, seed) for seed in seeds for name, cfg in recipes]
    # runs still to train (a test-time variant's test is not counted)
    left = sum(not osp.isfile(result_file(out_dir, n, s))
               and sources[n] is None and n not in fixed
               and trained_there(n, s)[0] is None for n, _, s in jobs)
    results: Dict[int, dict] = {}
    spent, fresh = 0.0, 0
    pending = list(enumerate(jobs, 1))
    missing = []  # runs a tabulation (train=False) leaves out
    in_progress = []  # runs of other processes, with wait=False
    while pending:
        waiting = []
        for k, (name, config, seed) in pending:
            path = result_file(out_dir, name, seed)
            done = osp.isfile(path)
            if not done and not train:
                missing.append([name, seed])
                log(f'[compare {k}/{len(jobs)}] {name}, seed {seed}: not '
                    'finished, left out (nothing is trained)')
                continue
            source = sources[name]
            if not done and source is not None and not osp.isfile(
                    result_file(out_dir, source, seed)) and (
                    held_elsewhere(out_dir, source, seed) or any(
                        (n, s) == (source, seed)
                        for _, (n, _, s) in waiting)):
                # a test-time variant of weights still being trained
                # (here by another process, or in another set's work dir)
                waiting.append((k, (name, config, seed)))
                log(f'[compare {k}/{len(jobs)}] {name}, seed {seed}: tests '
                    f'the weights of {source!r}, which another process is '
                    'still training, later')
                continue
            trained_in, busy = (None, False) if done else \
                trained_there(name, seed)
            if busy:
                waiting.append((k, (name, config, seed)))
                log(f'[compare {k}/{len(jobs)}] {name}, seed {seed}: trains '
                    f'as {trained_elsewhere[name]!r}, which another process '
                    f'is training in {weights_from}, later')
                continue
            lock = None if done else RunLock(osp.dirname(path))
            if lock is not None and not lock.acquire():
                # another process of this comparison trains it now
                waiting.append((k, (name, config, seed)))
                log(f'[compare {k}/{len(jobs)}] {name}, seed {seed}: '
                    f'being trained by process {lock.holder()}, later')
                continue
            eta = ''
            if fresh:
                eta = (f', about {math.ceil(spent / fresh * left / 60)} '
                       'min left')
            doing = 'training' if sources[name] is None else \
                f'testing the weights of {sources[name]!r}'
            if name in fixed:
                doing = 'testing the weights its config loads (trains '\
                    'nothing)'
            if trained_in is not None:
                doing = ('testing the weights trained in '
                         f'{osp.dirname(trained_in)}')
            elif name in trained_elsewhere and not done:
                doing += (f' (no finished run of '
                          f'{trained_elsewhere[name]!r} with its weights '
                          f'in {weights_from})')
            log(f'[compare {k}/{len(jobs)}] {name}, seed {seed}: '
                f'{"already done" if done else doing}{eta}')
            start = time.perf_counter()
            if done:
                results[k] = read_result(path, budgets[name], cfg_options)
                continue
            try:
                results[k] = run_recipe(
                    name, config, seed, budgets[name], data_root, betas,
                    out_dir, cfg_options, weights_of=sources[name],
                    transfer_root=transfer_root, trained_in=trained_in,
                    test_only=name in fixed)
            finally:
                lock.release()
            if sources[name] is None and trained_in is None and \
                    name not in fixed:
                spent += time.perf_counter() - start
                fresh += 1
                left -= 1
        if waiting and not wait:
            in_progress = [[n, s] for _, (n, _, s) in waiting]
            log(f'{len(waiting)} run(s) left to other processes, not '
                'waited for')
            break
        if waiting and len(waiting) == len(pending):
            # everything left is in other processes' hands: wait for them
            time.sleep(wait_s)
        pending = waiting
    if not results and in_progress:
        log('nothing finished yet to tabulate')
        return dict(set=set_name, runs=[], in_progress=in_progress)
    if not train and not results:
        raise ValueError(
            f'nothing to tabulate: no finished run of these recipes and '
            f'seeds in {out_dir} (with this budget); train them, or put a '
            'record there with --restore')
    results = [results[k] for k in sorted(results)]
    summary = summarize(results, betas, reference,
                        SET_COLUMNS.get(set_name))
    record = dict(
        set=set_name, recipes=[dict(name=n, config=c) for n, c in recipes],
        seeds=list(seeds), budget=asdict(budget), data_root=data_root,
        betas=list(betas),
        # the device MMEngine's Runner trained on (a GPU when one is seen)
        machine=machine_line(device=get_device()) if train else None,
        date=time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()),
        runs=results, summary=summary)
    if not train:
        record['missing'] = missing
    if in_progress:
        record['in_progress'] = in_progress
    if transfer_root is not None:
        record['transfer_root'] = transfer_root
    if weights_from is not None:
        record['weights_from'] = weights_from
    if cfg_options:
        record['cfg_options'] = _options(cfg_options)
    top, ceiling_md = ceiling(set_name, ceiling_record, summary['columns'])
    if top is not None:
        record['ceiling'] = top
    with open(osp.join(out_dir, 'compare.json'), 'w') as f:
        json.dump(record, f, indent=1)
    markdown = to_markdown(summary)
    if ceiling_md:
        markdown += '\n' + ceiling_md
    if missing:
        markdown += '\n\nLeft out (not finished): ' + ', '.join(
            f'{name} seed {seed}' for name, seed in missing) + '.'
    if in_progress:
        markdown += ('\n\nLeft out (being trained by another process): '
                     + ', '.join(f'{name} seed {seed}'
                                 for name, seed in in_progress) + '.')
    with open(osp.join(out_dir, 'compare.md'), 'w') as f:
        f.write(markdown + '\n')
    plot(summary, betas, osp.join(out_dir, 'compare.png'))
    log(markdown)
    return record
