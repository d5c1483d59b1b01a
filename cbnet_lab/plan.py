"""What a comparison runs, checked before its first run: its runs, one
:class:`Job` per recipe and seed (:func:`plan_jobs`), which recipe's
weights each recipe tests (:func:`weights_sources`), which rows train as
another set's (:func:`trained_as`), the condition every recipe is tested
on first (:func:`reference_condition`), and the data, second test set
and pretrained files the runs need (:func:`check_inputs`), so that a
missing file stops a comparison before it trains anything.
"""
import os.path as osp
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

from cbnet_tools.pretrained import require_pretrained

from .config_edits import Budget, read_config
from .run_files import check_weights_from, find_trained, result_file
from .sets import (SET_TRAINED_AS, SETS, Recipe, data_condition,
                   resolve_recipes, row_budget, set_rows)


@dataclass
class Job:
    """One run of a comparison (a recipe and a seed), as an executor hands
    it to :func:`cbnet_lab.run.execute`: what :func:`cbnet_lab.run
    .run_recipe` is given, where it stands in the comparison, what it
    does. Picklable, for the executors that run it in another process.

    Attributes:
        index (int): Its place in the comparison (1-based, seed-major).
        total (int): How many runs the comparison has.
        name (str): The recipe.
        config (str): Its config file.
        seed (int): The seed.
        budget (Budget): The recipe's budget (its row's over the set's).
        data_root (str): The dataset.
        betas (list[float]): The fog densities it is tested on.
        out_dir (str): The comparison's work dir.
        cfg_options (dict, optional): Overrides of every config.
        condition (str, optional): The name of its own test set where
            that is real data (:func:`reference_condition`; None:
            Cityscapes-layout clear and foggy val).
        transfer_test (dict, optional): A second test set (its set's
            ``transfer_test``).
        transfer_root (str, optional): Its folder, in place of its
            ``data_root``.
        weights_of (str, optional): The recipe whose weights of the same
            seed it tests (trains nothing; runs after that one).
        test_only (bool): Trains nothing: tests the weights its config
            loads.
        keep_img_scale (bool): Its config's ``Resize`` sizes stay (its row
            says so), the budget's ``img_scale`` does not apply.
        trained_in (str, optional): The ``result.json`` of the run of
            another set that trained it (trains nothing).
        doing (str): What it does, for the log.
    """
    index: int
    total: int
    name: str
    config: str
    seed: int
    budget: Budget
    data_root: str
    betas: List[float]
    out_dir: str
    cfg_options: Optional[dict] = None
    condition: Optional[str] = None
    transfer_test: Optional[dict] = None
    transfer_root: Optional[str] = None
    weights_of: Optional[str] = None
    test_only: bool = False
    keep_img_scale: bool = False
    trained_in: Optional[str] = None
    doing: str = 'training'

    @property
    def result(self) -> str:
        """Its ``result.json`` (:func:`cbnet_lab.run_files.result_file`)."""
        return result_file(self.out_dir, self.name, self.seed)

    @property
    def trains(self) -> bool:
        """Whether it trains (else it tests weights trained elsewhere)."""
        return self.weights_of is None and not self.test_only and \
            self.trained_in is None

    @property
    def after(self) -> Optional[Tuple[str, int]]:
        """The run it waits for: (recipe, seed) of the weights it tests."""
        return None if self.weights_of is None else \
            (self.weights_of, self.seed)

    def say(self, what: str) -> str:
        """A log line about it."""
        return (f'[compare {self.index}/{self.total}] {self.name}, seed '
                f'{self.seed}: {what}')


def plan_jobs(recipes: Sequence[Tuple[str, str]], seeds: Sequence[int],
              budget: Budget, data_root: str, betas: Sequence[float],
              out_dir: str, cfg_options: Optional[dict] = None,
              set_name: Optional[str] = None,
              transfer_root: Optional[str] = None,
              weights_from: Optional[str] = None,
              weights_of: Optional[Dict[str, str]] = None,
              condition: Optional[str] = None) -> List[Job]:
    """Every run of a comparison, seed-major (a comparison cut short still
    has every recipe at the seeds it finished).

    Args:
        recipes (Sequence[tuple[str, str]]): (name, config path).
        seeds (Sequence[int]): Seeds; every recipe runs with each.
        budget (Budget): The set's budget (a row may have its own over
            it: :func:`cbnet_lab.sets.row_budget`).
        data_root (str): Dataset root.
        betas (Sequence[float]): Fog densities to test on.
        out_dir (str): The comparison's work dir.
        cfg_options (dict, optional): Overrides for every config.
        set_name (str, optional): The built-in set the recipes are of; its
            ``transfer_test`` is every run's second test set.
        transfer_root (str, optional): The folder of that second test
            set, in place of its ``data_root``.
        weights_from (str, optional): The work dir of the set some rows
            train as (:func:`trained_as`): each seed finished there is
            tested, not trained (:func:`cbnet_lab.run_files.find_trained`).
        weights_of (dict, optional): Test-time variants among the recipes
            without a set row: name -> the recipe whose weights it tests
            (:func:`weights_sources`).
        condition (str, optional): The name of the recipes' own test set
            where that is real data (their :func:`reference_condition`).

    Returns:
        list[Job]: The runs, in order.

    Raises:
        ValueError: A test-time variant without its source
            (:func:`weights_sources`), a malformed row budget, rows that do
            not train as ``weights_from``'s, or a run there of another
            budget or overrides.
    """
    rows = set_rows(set_name, recipes)
    transfer = None if set_name is None else SETS[set_name].transfer_test
    sources = weights_sources(recipes, rows, weights_of)
    budgets = {n: row_budget(budget, rows.get(n)) for n, _ in recipes}
    elsewhere = trained_as(set_name, recipes) if weights_from else {}
    if elsewhere:
        check_weights_from(weights_from, data_root)
    pairs = [(name, config, seed) for seed in seeds
             for name, config in recipes]
    jobs = []
    for index, (name, config, seed) in enumerate(pairs, 1):
        row = rows.get(name)
        job = Job(index, len(pairs), name, config, seed, budgets[name],
                  data_root, list(betas), out_dir, cfg_options, condition,
                  transfer, transfer_root, weights_of=sources[name],
                  test_only=bool(row and row.test_only),
                  keep_img_scale=bool(row and row.keep_img_scale))
        if job.test_only:
            job.doing = ('testing the weights its config loads (trains '
                         'nothing)')
        elif job.weights_of is not None:
            job.doing = f'testing the weights of {job.weights_of!r}'
        elif name in elsewhere and not osp.isfile(job.result):
            job.trained_in = find_trained(weights_from, elsewhere[name],
                                          seed, job.budget, cfg_options)
            job.doing = (
                f'testing the weights trained in '
                f'{osp.dirname(job.trained_in)}' if job.trained_in else
                f'training (no finished run of {elsewhere[name]!r} with '
                f'its weights in {weights_from})')
        jobs.append(job)
    return jobs


def weights_sources(
        recipes: Sequence[Tuple[str, str]],
        rows: Optional[Dict[str, Recipe]] = None,
        weights_of: Optional[Dict[str, str]] = None
) -> Dict[str, Optional[str]]:
    """Which recipe's weights each recipe tests (None: its own, trained).

    A set file's row with ``weights_of = NAME``, or a recipe that
    ``weights_of`` names (``compare_recipes.py --weights-of``: a
    ``--configs`` recipe has no row), tests the weights that the earlier
    recipe ``NAME`` trains.

    Args:
        recipes (Sequence[tuple[str, str]]): (name, config path), in order.
        rows (dict, optional): Recipe name -> its set file row
            (:func:`cbnet_lab.sets.set_rows`).
        weights_of (dict, optional): Recipe name -> the recipe whose
            weights it tests, over its row's.

    Returns:
        dict: recipe name -> name of the recipe whose weights it tests.

    Raises:
        ValueError: ``weights_of`` names no recipe, or a recipe's source is
            not an earlier recipe of the comparison that trains.
    """
    rows, given = rows or {}, dict(weights_of or {})
    names = [name for name, _ in recipes]
    unknown = sorted(set(given) - set(names))
    if unknown:
        raise ValueError(f'weights_of: no recipe named {unknown}; the '
                         f'recipes are {names}')
    sources = {}
    for name in names:
        row = rows.get(name)
        source = given.get(name, None if row is None else row.weights_of)
        if source is not None and sources.get(source, 'missing') is not None:
            raise ValueError(
                f'recipe {name!r} tests the weights of {source!r}, which is '
                'not an earlier recipe of this comparison that trains (give '
                f'it too, before {name!r})')
        sources[name] = source
    return sources


def trained_as(set_name: Optional[str],
               recipes: Sequence[Tuple[str, str]]) -> Dict[str, str]:
    """Which of ``recipes`` train exactly as a row of another set.

    Args:
        set_name (str, optional): The comparison's set
            (:data:`cbnet_lab.sets.SET_TRAINED_AS`).
        recipes (Sequence[tuple[str, str]]): (name, config path).

    Returns:
        dict: recipe name -> the other set's row name, for the recipes of
        ``recipes`` that the set names.

    Raises:
        ValueError: The set has no such rows, or a row's config differs
            from the other row's in more than its ``transfer_*`` keys (the
            variables of the fog-transfer base): training one would not be
            training the other.
    """
    spec = SET_TRAINED_AS.get(set_name)
    if spec is None:
        raise ValueError(
            f'no row of the set {set_name!r} trains as another set\'s '
            '(--weights-from is for ' + ', '.join(sorted(SET_TRAINED_AS)) +
            ')')

    def training_keys(config: str) -> dict:
        return {k: v for k, v in read_config(config).to_dict().items()
                if not k.startswith('transfer_')}

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
                'transfer_* keys may)')
        found[name] = other
    return found


def reference_condition(recipes: Sequence[Tuple[str, str]]) -> str:
    """The condition every recipe is tested on first: ``'clear'``, or the
    name of the real data all the recipes' configs are written for (the
    condition of their ``data_root``: :func:`cbnet_lab.sets
    .data_condition`).

    Raises:
        ValueError: The recipes are written for data of different
            conditions.
    """
    names = {name: data_condition(read_config(config).get('data_root')) or
             'clear' for name, config in recipes}
    if len(set(names.values())) > 1:
        raise ValueError(
            'the recipes are tested on different data (the condition of '
            f'each config\'s data_root: {names}); compare recipes of one '
            'kind at a time')
    return next(iter(names.values()))


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


def check_transfer(jobs: Sequence[Job], transfer_root: Optional[str],
                   reference: str = 'clear') -> None:
    """The runs' second test set (their set's ``transfer_test``), before
    any training: its VOC folder exists (``transfer_root``, else the set
    file's ``data_root``) and its name is not that of the recipes' own
    test set (``reference``); ``transfer_root`` without a second test set
    is an error."""
    spec = next((job.transfer_test for job in jobs if job.transfer_test),
                None)
    if spec is None:
        if transfer_root is not None:
            raise ValueError(
                f'--transfer-root {transfer_root}: the recipes have no '
                "second test set (their set's transfer_test), so it would "
                'not be read')
        return
    if spec['condition'] == reference:
        raise ValueError(
            f"the second test set {spec['condition']!r} (the set's "
            'transfer_test) is also the name of the recipes\' own test '
            'set; give it another name')
    root = transfer_root or spec['data_root']
    if not osp.isdir(root):
        raise FileNotFoundError(
            f"the recipes are also tested on {spec['condition']!r}, the VOC "
            f'folder {root}, which does not exist; give it with '
            '--transfer-root')


def check_pretrained(recipes: Sequence[Tuple[str, str]],
                     sources: Dict[str, Optional[str]]) -> None:
    """Every pretrained file the trained recipes load, before the first
    run (not hours later): a missing one is an error naming the command
    that fetches it (:func:`cbnet_tools.pretrained
    .require_pretrained`). Test-time variants load no trunk."""
    for name, config in recipes:
        if sources[name] is None:
            require_pretrained(read_config(config))


def check_inputs(recipes: Sequence[Tuple[str, str]], jobs: Sequence[Job],
                 reference: str, data_root: str, betas: Sequence[float],
                 transfer_root: Optional[str] = None) -> None:
    """What the runs read, before the first one: the data
    (:func:`check_data`), the second test set (:func:`check_transfer`)
    and the pretrained files (:func:`check_pretrained`)."""
    check_data(reference, data_root, betas)
    check_transfer(jobs, transfer_root, reference)
    check_pretrained(recipes, {job.name: job.weights_of for job in jobs})
