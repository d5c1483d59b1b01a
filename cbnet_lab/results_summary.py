"""The README's results table, printed from the records its rows quote.

A spec (``docs/results_summary.yml``) names, per row, the set (in words),
its metrics, its record and condition, and per column the recipes it
quotes; this module reads the records' raw runs and prints each quote as
``mean +- std`` over their seeds (the sample std, one decimal, in percent:
what ``compare_recipes.py --report-only`` prints for the same record), so
no figure of the table is typed by hand::

    columns: [MMDet's stock cascade, CBNet (paper), CBNet, revised]
    rows:
    - set: generated benchmark, clear val (3 seeds)
      metrics: [mask AP, box AP]          # names of cbnet_lab.metric_keys
      metric: mask AP / box AP            # the metric column (optional)
      record: docs/accuracy/parts_bench.json
      condition: clear
      doc: [accuracy, docs/accuracy.md#a-cbnet-that-wins-3-seeds]
      cells:                              # one list of quotes per column
      - - recipe: stock (GELU, OPE)
      - - recipe: CBNet
          text: '{} (3 seeds)'            # {} is the figures
      - - recipe: CBNet revised
          bold: [mask AP]                 # or true: every figure
        - text: not run                   # words only

A quote may give its own ``record``, ``condition`` and ``metrics``;
``spread: false`` prints the mean alone, for rows that train nothing
(their seeds must agree); ``like_for_like: {model, threads, proposals,
sizes}`` quotes the inference time over Swin-S's of a like-for-like
record (:func:`cbnet_lab.record_tables.like_for_like`'s ratios). A
column without quotes shows ``-``. The last column links the row's doc
section and every record its quotes read.

``tools/misc/record_table.py results-summary docs/results_summary.yml``
prints it; the README's generated region names that command.
"""
import os.path as osp
from typing import Callable, Dict, List, Optional, Sequence

import numpy as np

from cbnet_tools.markdown import markdown_table

from .metric_keys import METRICS

#: The keys a quote may hold.
QUOTE_KEYS = frozenset({'recipe', 'record', 'condition', 'metrics', 'text',
                        'bold', 'spread', 'like_for_like'})


def seed_values(record: dict, recipe: str, condition: str,
                metric: str) -> List[float]:
    """``metric`` (in percent) of every run of ``recipe`` on
    ``condition``, in run order; a value below 0 (MMDet's -1: nothing to
    evaluate) or missing is left out, as the comparison's tables do.

    Raises:
        KeyError: no run of ``recipe`` in the record, or none reports
            ``metric`` on ``condition`` (the record's recipes or
            conditions are named).
    """
    key, scale = METRICS[metric]
    runs = [r for r in record.get('runs', []) if r['recipe'] == recipe]
    if not runs:
        held = sorted({r['recipe'] for r in record.get('runs', [])})
        raise KeyError(f'no run of {recipe!r} in the record ({held})')
    values = []
    for run in runs:
        value = (run['metrics'].get(condition) or {}).get(key)
        if value is not None and value >= 0:
            values.append(float(value) * scale)
    if not values:
        held = sorted({c for r in runs for c in r['metrics']})
        raise KeyError(f'{recipe!r} reports no {metric} on {condition!r} '
                       f'(its conditions: {held})')
    return values


def figure(values: Sequence[float], spread: bool = True) -> str:
    """``mean +- std`` (sample std) with one decimal; the mean alone
    without ``spread``.

    Raises:
        ValueError: ``spread`` off for values that differ.
    """
    arr = np.asarray(values, dtype=float)
    if not spread:
        if np.ptp(arr) > 1e-9:
            raise ValueError(f'spread: false for values that differ over '
                             f'the seeds ({list(values)}): show the std')
        return f'{arr.mean():.1f}'
    std = float(arr.std(ddof=1)) if arr.size > 1 else 0.0
    return f'{arr.mean():.1f} +- {std:.1f}'


def _bold(text: str, on: bool) -> str:
    return f'**{text}**' if on else text


def quote(spec: dict, row: dict, load: Callable) -> tuple:
    """(the quote's text, the record it read or ``None``)."""
    unknown = set(spec) - QUOTE_KEYS
    if unknown:
        raise ValueError(f'a quote of row {row["set"]!r} has unknown keys '
                         f'{sorted(unknown)} ({sorted(QUOTE_KEYS)})')
    template = spec.get('text', '{}')
    if 'recipe' not in spec and 'like_for_like' not in spec:
        return template, None
    path = spec.get('record', row.get('record'))
    record = load(path)
    bold = spec.get('bold', False)
    if 'like_for_like' in spec:
        from .record_tables import like_for_like_ratio
        lfl = spec['like_for_like']
        ratios = [like_for_like_ratio(record, lfl['model'], str(size),
                                      str(lfl['threads']),
                                      int(lfl['proposals']))
                  for size in lfl['sizes']]
        cells = [f'{r:.2f}' for r in ratios]
        return template.format(_bold(' / '.join(cells), bold is True)), path
    condition = spec.get('condition', row.get('condition'))
    metrics = spec.get('metrics', row['metrics'])
    parts = []
    for metric in metrics:
        values = seed_values(record, spec['recipe'], condition, metric)
        text = figure(values, spec.get('spread', True))
        parts.append((text, bold is True or metric in (bold or ())))
    if all(on for _, on in parts):  # one pair of marks around them all
        return template.format(_bold(' / '.join(t for t, _ in parts),
                                     True)), path
    return template.format(' / '.join(_bold(t, on) for t, on in parts)), \
        path


def results_summary(spec: dict, root: str = '.',
                    load: Optional[Callable] = None) -> str:
    """The table ``spec`` describes (module docstring), its records read
    under ``root``.

    Raises:
        ValueError: a row with another number of cells than columns, or a
            malformed quote.
        KeyError: a recipe, condition or metric its record does not hold.
    """
    if load is None:
        from .record_tables import load as load_file
        cache: Dict[str, dict] = {}

        def load(path):
            if path not in cache:
                cache[path] = load_file(osp.join(root, path))
            return cache[path]

    columns = list(spec['columns'])
    out = []
    for row in spec['rows']:
        cells = row.get('cells', [])
        if len(cells) != len(columns):
            raise ValueError(f'row {row["set"]!r}: {len(cells)} cells '
                             f'under {len(columns)} columns')
        texts, records = [], []
        for quotes in cells:
            shown = []
            for q in quotes or []:
                text, path = quote(q, row, load)
                shown.append(text)
                if path and path not in records:
                    records.append(path)
            texts.append('; '.join(shown) if shown else '-')
        links = []
        if row.get('doc'):
            label, target = row['doc']
            links.append(f'[{label}]({target})')
        links += [f'[record]({path})' for path in records]
        metric = row.get('metric', ' / '.join(row.get('metrics', [])))
        out.append([row['set'], metric] + texts + [', '.join(links)])
    return '\n'.join(markdown_table(
        [spec.get('set_header', 'set'), 'metric'] + columns + ['source'],
        out))
