"""A run's files: where a recipe's run of one seed keeps its record and
weights (``{work_dir}/{slug(name)}/seed{seed}/``: ``result.json``, the
last ``iter_N.pth``), reading them back against the comparison's budget
and overrides, writing a saved record's runs back (``--restore``), and
finding a finished run in another set's work dir (``--weights-from``).

The layout is the harness's on-disk contract: records, resumes and
restores of every earlier comparison read it.
"""
import json
import os
import os.path as osp
import re
from dataclasses import asdict
from typing import Optional

from .config_edits import Budget, checkpoint_iter, resume_file


def slug(name: str) -> str:
    """A folder name for a recipe name (``+shape +edge`` -> ``shape_edge``)."""
    return re.sub(r'[^A-Za-z0-9.]+', '_', name).strip('_') or 'recipe'


def result_file(out_dir: str, name: str, seed: int) -> str:
    """Where :func:`cbnet_lab.run.run_recipe` keeps the result of one
    recipe and seed."""
    return osp.join(out_dir, slug(name), f'seed{seed}', 'result.json')


def checkpoint_file(out_dir: str, name: str, seed: int,
                    budget: Budget) -> str:
    """The weights that :func:`cbnet_lab.run.run_recipe` tests for one
    recipe and seed."""
    last = f'iter_{budget.iters}.pth' if budget.iters > 0 else \
        'untrained.pth'
    return osp.join(osp.dirname(result_file(out_dir, name, seed)), last)


def resume_iter(work_dir: str) -> Optional[int]:
    """The iteration of :func:`cbnet_lab.config_edits.resume_file`, None
    to start from 0."""
    path = resume_file(work_dir)
    return None if path is None else checkpoint_iter(path)


def recorded_options(cfg_options: Optional[dict]) -> dict:
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
    had, now = result.get('cfg_options', {}), recorded_options(cfg_options)
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
                 cfg_options: Optional[dict] = None) -> Optional[str]:
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
        str: The run's ``result.json`` when it is finished with its
        weights on disk, else None (never run there, not finished yet, or
        restored from a record without its weights).

    Raises:
        ValueError: The run there was trained under another budget or
            overrides.
    """
    path = result_file(weights_from, name, seed)
    if not osp.isfile(path):
        return None
    read_result(path, budget, cfg_options)  # the same budget and overrides
    weights = checkpoint_file(weights_from, name, seed, budget)
    return path if osp.isfile(weights) else None
