"""Train recipes on the same data, budget and seeds, and compare them.

The comparison harness behind ``tools/analysis_tools/compare_recipes.py``,
split by what it does: the sets and their recipes (:mod:`cbnet_lab.sets`),
what a comparison runs, checked before it starts (:mod:`cbnet_lab.plan`),
one run (:mod:`cbnet_lab.run`) and its files (:mod:`cbnet_lab.run_files`),
the summary over seeds and its record (:mod:`cbnet_lab.summary`); every
config edit is :mod:`cbnet_lab.config_edits`'. This module is its face:
:func:`compare`, and the names the command lines and tests use.

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
import math
import os
import os.path as osp
import time
from dataclasses import asdict
from typing import Callable, Dict, Optional, Sequence, Tuple

from mmengine.device import get_device

from .config_edits import Budget, configs_root
from .plan import (check_data, check_pretrained, check_transfer,
                   reference_condition, trained_as, weights_sources)
from .report import machine_line
from .run import run_recipe, with_front_end
from .run_files import (RunLock, check_weights_from, checkpoint_file,
                        find_trained, held_elsewhere, read_result,
                        recorded_options, restore_runs, result_file,
                        resume_iter, slug)
from .sets import (PRESETS, RECIPE_SETS, SET_CEILINGS, SET_COLUMNS,
                   SET_PRESETS, SET_TRAINED_AS, SETS, resolve_recipes,
                   row_budget, set_rows)
from .summary import (DETECTION_COLUMNS, PROPOSAL_COLUMNS, ceiling,
                      condition_names, mean_std, pick_columns, summarize,
                      write)

__all__ = [
    'compare', 'Budget', 'configs_root', 'SETS', 'RECIPE_SETS', 'PRESETS',
    'SET_PRESETS', 'SET_COLUMNS', 'SET_CEILINGS', 'SET_TRAINED_AS',
    'resolve_recipes', 'set_rows', 'row_budget', 'weights_sources',
    'trained_as', 'reference_condition', 'check_data', 'check_transfer',
    'check_pretrained', 'run_recipe', 'with_front_end', 'slug',
    'result_file', 'checkpoint_file', 'resume_iter', 'read_result',
    'restore_runs', 'check_weights_from', 'find_trained',
    'DETECTION_COLUMNS', 'PROPOSAL_COLUMNS', 'condition_names',
    'pick_columns', 'mean_std', 'summarize', 'ceiling'
]


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
        record['cfg_options'] = recorded_options(cfg_options)
    top, ceiling_md = ceiling(set_name, ceiling_record, summary['columns'])
    if top is not None:
        record['ceiling'] = top
    write(record, out_dir, ceiling_md, log)
    return record
