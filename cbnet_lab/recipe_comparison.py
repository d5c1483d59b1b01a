"""Train recipes on the same data, budget and seeds, and compare them.

The comparison harness behind ``tools/analysis_tools/compare_recipes.py``,
split by what it does: the sets and their recipes (:mod:`cbnet_lab.sets`),
what a comparison runs, checked before it starts (:mod:`cbnet_lab.plan`),
one run (:mod:`cbnet_lab.run`) and its files (:mod:`cbnet_lab.run_files`),
where the runs run (:mod:`cbnet_lab.executors`: in this process, in N
worker processes, as Ray tasks), the summary over seeds and its record
(:mod:`cbnet_lab.summary`); every config edit is in
:mod:`cbnet_lab.config_edits`. This module is its face: :func:`compare`,
and the names the command lines and tests use.

Every recipe is an MMDet config; each is trained with MMEngine's
``Runner`` under one :class:`Budget` (iterations, batch, lr schedule) and
one seed at a time, on the dataset at ``data_root`` (any dataset in the
Cityscapes layout: the generated one or the real Cityscapes /
Foggy Cityscapes), then tested on clear val and on foggy val for each beta
through :func:`cbnet_lab.ap_drop.ap_drop`. Each run writes its
``result.json``; a rerun skips finished runs, and a run cut short resumes
from its last checkpoint (resumable). The results are summarised as
mean +- std over seeds per recipe and condition.

Test-time variants. A set file's row with ``weights_of = NAME`` (or a
``--configs`` recipe named in ``weights_of``) is not trained: each seed
tests the weights that recipe ``NAME`` trained for that seed, in the same
comparison (listed before it), under the variant's own test settings
(``model.test_cfg``, test pipeline). That compares, say, test-time
proposal counts on the very same weights.

A test-time variant runs after its source run of the same seed; a source
whose checkpoint is missing (never trained, or restored from a record
without its weights) is an error naming the file.

Transfer. The runs of a set whose file sets ``transfer_test`` (the
``fog_transfer`` set: trained on clear COCO street photos) are tested on
their own test set and then on that real-fog VOC folder
(``transfer_root``, default the set file's), two conditions per run and
the drop between them (:func:`cbnet_lab.ap_drop.ap_drop`).

Runs trained by another set. Some rows of a set train exactly what a
row of another set trains (:data:`SET_TRAINED_AS`: the fog_transfer set's
clear-only rows are the coco_street set's rows with a second test set;
checked: the two configs must be equal but for their ``transfer_*``
keys). Given ``weights_from`` (the other set's work dir:
same budget, overrides and data), each seed's finished run there is
tested here instead of trained again: its checkpoint is linked into this
run's folder, and the run records its train time and where it was
trained (``trained_in``, ``trained_as``). A seed with no finished run
there, or one without its weights (a restored record), is trained here as
usual.

Real data. When the recipes' configs are written for real data (their
``data_root`` a folder of the presets file's ``test_conditions``, which
names its condition: DAWN's ``'real fog'``, set ``realfog`` and the
pretrained ones; ``'coco street'``), ``data_root`` is that dataset (a VOC
folder, or the COCO street split) and each run is tested on the config's
own test set under that name, with no foggy betas
(:func:`cbnet_lab.ap_drop.ap_drop`); every recipe of a comparison must
then be of the same condition.
"""
import os
import time
from dataclasses import asdict
from typing import Callable, Optional, Sequence, Tuple

from .config_edits import Budget, configs_root
from .executors import Executor, InProcess, sweep
from .plan import (check_data, check_inputs, check_pretrained, check_transfer,
                   plan_jobs, reference_condition, trained_as,
                   weights_sources)
from .run import run_recipe, with_front_end
from .run_files import (check_weights_from, checkpoint_file, find_trained,
                        read_result, recorded_options, restore_runs,
                        result_file, resume_iter, slug)
from .sets import (PRESETS, RECIPE_SETS, SET_CEILINGS, SET_COLUMNS,
                   SET_PRESETS, SET_TRAINED_AS, SETS, resolve_recipes,
                   row_budget, set_rows)
from .summary import (DETECTION_COLUMNS, PROPOSAL_COLUMNS, ceiling,
                      condition_names, mean_std, pick_columns, summarize,
                      write)

__all__ = [
    'compare', 'Budget', 'configs_root', 'SETS', 'RECIPE_SETS', 'PRESETS',
    'SET_PRESETS', 'SET_COLUMNS', 'SET_CEILINGS', 'SET_TRAINED_AS',
    'resolve_recipes', 'set_rows', 'row_budget', 'plan_jobs',
    'weights_sources', 'trained_as', 'reference_condition', 'check_data',
    'check_transfer', 'check_pretrained', 'run_recipe', 'with_front_end',
    'slug', 'result_file', 'checkpoint_file', 'resume_iter', 'read_result',
    'restore_runs', 'check_weights_from', 'find_trained',
    'DETECTION_COLUMNS', 'PROPOSAL_COLUMNS', 'condition_names',
    'pick_columns', 'mean_std', 'summarize', 'ceiling'
]


def compare(recipes: Sequence[Tuple[str, str]], seeds: Sequence[int],
            budget: Budget, data_root: str, betas: Sequence[float],
            out_dir: str, cfg_options: Optional[dict] = None,
            log: Callable[[str], None] = print,
            set_name: Optional[str] = None, train: bool = True,
            transfer_root: Optional[str] = None,
            ceiling_record: Optional[str] = None,
            weights_from: Optional[str] = None,
            executor: Optional[Executor] = None,
            weights_of: Optional[dict] = None) -> dict:
    """Run every recipe with every seed, then summarise, tabulate, plot.

    Writes ``compare.json`` (runs, summary, budget, machine, date),
    ``compare.md`` and ``compare.png`` into ``out_dir``.

    Args:
        recipes (Sequence[tuple[str, str]]): (name, config path).
        seeds (Sequence[int]): Seeds; every recipe runs with each.
        budget (Budget): Training budget of every run.
        data_root (str): Dataset root (Cityscapes layout, with
            ``leftImg8bit_foggy`` for the betas; or the real data of
            recipes written for it: :func:`reference_condition`).
        betas (Sequence[float]): Fog densities to test on (none for real
            data).
        out_dir (str): Output folder.
        cfg_options (dict, optional): Overrides for every config.
        log (callable): Progress printer.
        set_name (str, optional): Name of the built-in set, for the record.
        train (bool): False tabulates the finished runs in ``out_dir``
            alone (e.g. a record put there with :func:`restore_runs`):
            nothing is trained or tested, no data is read, the runs left
            out are listed (``missing`` in the record, a line under the
            tables) and the record names no machine (``machine`` None:
            the runs say nothing of where they were trained).
        transfer_root (str, optional): The real-fog folder of the set's
            ``transfer_test`` (None: the set file's); in the record when
            given.
        ceiling_record (str, optional): The ``compare.json`` of the set
            that is this set's in-domain ceiling (:data:`SET_CEILINGS`),
            tabulated under the results (``ceiling`` in the record).
        weights_from (str, optional): The work dir of the set whose rows
            some of this set's rows train as (:data:`SET_TRAINED_AS`):
            its finished runs are tested instead of trained
            (:func:`find_trained`); in the record when given.
        executor (optional): Where the runs run
            (:func:`cbnet_lab.executors.make_executor`); default one after
            another in this process.
        weights_of (dict, optional): Test-time variants among recipes
            without a set row (``--configs``): name -> the earlier recipe
            whose weights it tests, seed by seed (a set's rows say it with
            their ``weights_of``).

    Returns:
        dict: What ``compare.json`` holds.
    """
    executor = executor or InProcess()
    reference = reference_condition(recipes)
    # a tabulation (train=False) reads the runs here only
    jobs = plan_jobs(recipes, seeds, budget, data_root, betas, out_dir,
                     cfg_options, set_name, transfer_root,
                     weights_from if train else None, weights_of,
                     None if reference == 'clear' else reference)
    if train:  # a tabulation reads no data
        check_inputs(recipes, jobs, reference, data_root, betas,
                     transfer_root)
    os.makedirs(out_dir, exist_ok=True)
    results, missing = sweep(jobs, executor, log, train)
    if not results:
        raise ValueError(
            f'nothing to tabulate: no finished run of these recipes and '
            f'seeds in {out_dir} (with this budget); train them, or put a '
            'record there with --restore')
    summary = summarize(results, betas, reference,
                        SET_COLUMNS.get(set_name))
    record = dict(
        set=set_name, recipes=[dict(name=n, config=c) for n, c in recipes],
        seeds=list(seeds), budget=asdict(budget), data_root=data_root,
        betas=list(betas),
        # where MMEngine's Runner trained (a GPU when it sees one)
        machine=executor.machine() if train else None,
        date=time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()),
        runs=results, summary=summary)
    if not train:
        record['missing'] = missing
    for key, value in (('transfer_root', transfer_root),
                       ('weights_from', weights_from)):
        if value is not None:
            record[key] = value
    if cfg_options:
        record['cfg_options'] = recorded_options(cfg_options)
    top, ceiling_md = ceiling(set_name, ceiling_record, summary['columns'])
    if top is not None:
        record['ceiling'] = top
    write(record, out_dir, ceiling_md, log)
    return record
