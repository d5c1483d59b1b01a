"""The summary of a comparison: mean +- std over seeds per recipe,
condition and column (:func:`summarize`), the drop from the reference
condition, the in-domain ceiling read from another set's record
(:func:`ceiling`); written as ``compare.json``, ``compare.md`` and
``compare.png`` by :func:`write` (tables and plots:
:mod:`cbnet_lab.report`).
"""
import json
import os.path as osp
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from cbnet_tools.markdown import markdown_table

from .metric_keys import columns as metric_columns
from .report import plot, to_markdown
from .sets import SET_CEILINGS


#: Reported columns: (name, metric key, scale to percent). Detection sets
#: report COCO AP (``CocoMetric``) and mIoU (``CBNetInstanceMIoUMetric``);
#: RPN sets the average recall at 100/300/1000 proposals.
DETECTION_COLUMNS = metric_columns('box AP', 'box AP50', 'mask AP',
                                   'mask AP50', 'mIoU')
PROPOSAL_COLUMNS = metric_columns('AR@100', 'AR@300', 'AR@1000')


def condition_names(betas: Sequence[float],
                    reference: str = 'clear') -> List[str]:
    """Condition keys of :func:`cbnet_lab.ap_drop.ap_drop`: the reference
    (clear, or the real data's condition:
    :func:`cbnet_lab.plan.reference_condition`), then each beta."""
    return [reference] + [f'foggy beta={b}' for b in betas]


def pick_columns(results: Sequence[dict],
                 candidates: Optional[Sequence[tuple]] = None
                 ) -> Tuple[Tuple[str, str, float]]:
    """The columns whose metric some run reports (detection or proposal).

    A recipe that lacks a column's metric (a box-only detector's mask AP)
    shows ``-`` there, never 0.

    Args:
        results (Sequence[dict]): Outputs of :func:`cbnet_lab.run.run_recipe`.
        candidates (Sequence[tuple], optional): Column lists to try in
            order (default: :data:`DETECTION_COLUMNS`, then
            :data:`PROPOSAL_COLUMNS`); a set's own
            (:data:`cbnet_lab.sets.SET_COLUMNS`) goes first.

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
        results (Sequence[dict]): Outputs of :func:`cbnet_lab.run.run_recipe`.
        betas (Sequence[float]): The tested fog densities.
        reference (str): The first condition (clear, or the real data's
            name), which the drops are taken from.
        columns (Sequence[tuple], optional): ``(name, key, scale)`` to
            report before the default ones (a set's
            :data:`cbnet_lab.sets.SET_COLUMNS`).

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
    # the set's second test set comes after them (its transfer_test)
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


def ceiling(set_name: Optional[str], record_path: Optional[str],
            columns: Sequence[str]) -> Tuple[Optional[dict], str]:
    """The in-domain ceiling of a set (:data:`cbnet_lab.sets.SET_CEILINGS`)
    read from another set's saved record, never retrained.

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


def write(record: dict, out_dir: str, ceiling_md: str = '',
          log: Callable[[str], None] = print) -> str:
    """Write a comparison's record: ``compare.json`` (``record`` as it
    is), ``compare.md`` (:func:`cbnet_lab.report.to_markdown` of its
    summary, the ceiling's table, the runs left out) and ``compare.png``
    (:func:`cbnet_lab.report.plot`) into ``out_dir``; the markdown is
    logged and returned."""
    with open(osp.join(out_dir, 'compare.json'), 'w') as f:
        json.dump(record, f, indent=1)
    summary = record['summary']
    markdown = to_markdown(summary)
    if ceiling_md:
        markdown += '\n' + ceiling_md
    if record.get('missing'):
        markdown += '\n\nLeft out (not finished): ' + ', '.join(
            f'{name} seed {seed}' for name, seed in record['missing']) + '.'
    with open(osp.join(out_dir, 'compare.md'), 'w') as f:
        f.write(markdown + '\n')
    plot(summary, record['betas'], osp.join(out_dir, 'compare.png'))
    log(markdown)
    return markdown
