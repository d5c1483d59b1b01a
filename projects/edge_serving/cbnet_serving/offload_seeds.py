"""Offload tables of several local (edge) models, as mean +- std.

One :func:`.offload.offload_curve` result per trained seed of the edge
model (the same stream, the same kind of server) gives one table whose
rows are lined up by rule and level, not by threshold: the haze and
confidence rules at default thresholds sit at the deciles of what each
run measured, so "confidence, decile 0.3" is the 30 % least confident
frames of each seed's own edge model. Each row: mean +- std over the
seeds (sample std) of the offload rate, box AP, box AP50, the box AP of random
offloading at the same rate, the gain over it (per seed, then averaged),
the time per frame and the box AP on each condition's frames.
"""
import json
from typing import Dict, List, Sequence

import numpy as np

from cbnet_tools.markdown import markdown_table

#: Per-seed scalars of a row that are averaged.
KEYS = ('offload_rate', 'bbox_mAP', 'bbox_mAP_50', 'seconds')


def row_key(row: Dict) -> str:
    """A row's name across seeds (``None`` for random-offload rows: each
    policy row carries its own random control)."""
    rule = row.get('rule')
    if rule == 'random' or (rule is None
                            and row['policy'].startswith('random')):
        return None
    if row.get('quantile') is not None:
        return f"{rule}, decile {row['quantile']:g}"
    return row['policy']


def _stat(values: Sequence[float]) -> Dict:
    # the sample std (n - 1), as compare_recipes.py's tables give it
    return dict(mean=float(np.mean(values)),
                std=float(np.std(values, ddof=1)))


def combine(results: Sequence[Dict], names: Sequence[str] = None) -> Dict:
    """One table from per-seed offload results (``offload.json``).

    Raises ``ValueError`` when the results do not describe the same
    stream (frame count, conditions) scored the same way (calibrated or
    not), or when fewer than two are given."""
    if len(results) < 2:
        raise ValueError('give the offload results of at least two seeds '
                         f'of the local model, got {len(results)}')
    names = list(names or range(len(results)))
    first = results[0]
    for name, res in zip(names[1:], results[1:]):
        for field in ('frames', 'conditions', 'calibrated'):
            if res.get(field) != first.get(field):
                raise ValueError(
                    f'{name}: {field} {res.get(field)!r} differs from '
                    f'{names[0]}\'s {first.get(field)!r}: not runs over '
                    'the same stream scored the same way')
    if any('rule' not in r for res in results for r in res['rows']):
        raise ValueError('a result without row rules (written before '
                         'offload_eval.py named them): score it again')
    per = [{row_key(r): r for r in res['rows'] if row_key(r) is not None}
           for res in results]
    order = [k for k in per[0] if all(k in p for p in per)]
    partial = sorted({k for p in per for k in p} - set(order))
    conds = first['conditions']
    rows = []
    for key in order:
        runs = [p[key] for p in per]
        out = dict(row=key, policies=[r['policy'] for r in runs])
        for k in KEYS:
            out[k] = _stat([r[k] for r in runs])
        out['condition_ap'] = {
            c: _stat([r['condition_ap'][c]['bbox_mAP'] for r in runs])
            for c in conds}
        if all('random' in r for r in runs):
            rand = [r['random']['bbox_mAP'] for r in runs]
            out['random_bbox_mAP'] = _stat(rand)
            out['gain_over_random'] = _stat(
                [r['bbox_mAP'] - x for r, x in zip(runs, rand)])
        rows.append(out)
    return dict(seeds=names, frames=first['frames'], conditions=conds,
                calibrated=bool(first.get('calibrated')), rows=rows,
                partial=partial)


def to_markdown(table: Dict) -> str:
    """The table: one line per row, ``mean +- std`` over the seeds."""

    def ms(s, fmt='.1f', scale=1):
        return (f"{s['mean'] * scale:{fmt}} +- "
                f"{s['std'] * scale:{fmt}}")

    conds = table['conditions']
    head = (['row', 'offloaded', 'box AP', 'box AP50'] +
            [f'box AP {c}' for c in conds] +
            ['random at that rate', 'gain over random', 's/frame'])
    rows = []
    for r in table['rows']:
        cells = [r['row'], ms(r['offload_rate'], '.0f', 100) + ' %',
                 ms(r['bbox_mAP']), ms(r['bbox_mAP_50'])]
        cells += [ms(r['condition_ap'][c]) for c in conds]
        cells += [ms(r['random_bbox_mAP']) if 'random_bbox_mAP' in r
                  else '', ms(r['gain_over_random'])
                  if 'gain_over_random' in r else '',
                  ms(r['seconds'], '.3f')]
        rows.append(cells)
    lines = [f"{len(table['seeds'])} seeds "
             f"({', '.join(map(str, table['seeds']))}), "
             f"{table['frames']} frames"
             + (', scores calibrated per model' if table['calibrated']
                else '') + '; mean +- std over the seeds.', '']
    lines += markdown_table(head, rows)
    if table['partial']:
        lines += ['', 'Rows not in every seed (left out): ' +
                  ', '.join(table['partial']) + '.']
    return '\n'.join(lines) + '\n'


def load(paths: Sequence[str]) -> List[Dict]:
    """The ``offload.json`` records at ``paths``."""
    out = []
    for path in paths:
        with open(path) as f:
            out.append(json.load(f))
    return out
