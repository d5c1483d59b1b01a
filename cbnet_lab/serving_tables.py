"""Tables of the serving project's records (``docs/serving/``), printed by
``tools/misc/record_table.py`` for the docs' generated regions.

The records are JSON written by the serving tools
(``projects/edge_serving/tools/``: ``edge_speed.py``, ``load_test.py``,
``offload_eval.py``) and by the router's fallback check; they are read
here as data: the lab does not import the serving package (the layers of
``tests/test_layering.py``), and no model is built.
"""
from typing import Optional, Sequence

from cbnet_tools.markdown import markdown_table


def edge_speed(record: dict, reference: Optional[str] = None) -> str:
    """An ``edge_speed.py`` record: per model its runtime, the network's
    input, the median and 95th-percentile latency of one frame, frames per
    second, the CPU time per frame and the latency over ``reference``'s
    (default: the model the recorded command named with ``--reference``,
    else the last)."""
    results = record['results']
    models = record['meta']['models']
    if reference is None:
        command = record['meta'].get('command', '')
        reference = next((m for m in results
                          if f'--reference {m}' in command),
                         list(results)[-1])
    if reference not in results:
        raise KeyError(f'no model {reference!r} in the record '
                       f'({list(results)})')
    ref = results[reference]['p50']
    rows = [[name, models[name]['runtime'], 'x'.join(map(str, r['input'])),
             f"{r['p50']:.4f} / {r['p95']:.4f}", f"{r['fps']:.1f}",
             f"{r['cpu_p50']:.4f}", f"{r['p50'] / ref:.2f}"]
            for name, r in results.items()]
    return '\n'.join(markdown_table(
        ['model', 'runtime', 'network input (HxW)', 'latency p50 / p95 (s)',
         'frames/s', 'CPU time p50 (s)', f'latency / {reference}'], rows))


def load_test(records: Sequence[dict],
              names: Optional[Sequence[str]] = None) -> str:
    """``load_test.py`` records, one row each (``names``: what each server
    was, e.g. its replicas and batch size): per concurrency level the
    median latency and the throughput (the highest level also its 99th
    percentile), and the errors over all levels."""
    names = list(names or [str(i) for i in range(len(records))])
    if len(names) != len(records):
        raise ValueError(f'{len(names)} names for {len(records)} records')
    levels = [lv['concurrency'] for lv in records[0]['levels']]
    head = ['server'] + [f'concurrency {c}: p50 s / img/s'
                         for c in levels[:-1]] + \
        [f'concurrency {levels[-1]}: p50 / p99 s, img/s', 'errors']
    rows = []
    for name, record in zip(names, records):
        by_level = {lv['concurrency']: lv for lv in record['levels']}
        if sorted(by_level) != sorted(levels):
            raise ValueError(f'{name}: concurrency levels {sorted(by_level)}'
                             f', the first record has {levels}')
        cells = [f"{by_level[c]['p50_s']:.3f} / "
                 f"{by_level[c]['throughput_img_s']:.2f}"
                 for c in levels[:-1]]
        last = by_level[levels[-1]]
        cells.append(f"{last['p50_s']:.3f} / {last['p99_s']:.3f}, "
                     f"{last['throughput_img_s']:.2f}")
        errors = sum(lv['errors'] for lv in record['levels'])
        rows.append([name] + cells + [errors])
    return '\n'.join(markdown_table(head, rows))


#: Where a routed frame ends (the router's ``where``), in the table's order.
WHERE = ('server', 'local-fallback', 'local')


def fallback(record: dict) -> str:
    """The router's fallback check: per case (server up, slower than the
    timeout, down) the frames answered by the server, by the local model
    after a failed offload and by the local model alone, the errors of the
    failed offloads, and the time of an offloaded and of a kept frame
    (median / 95th percentile)."""
    rows = []
    for case, r in record.items():
        if case.startswith('_'):
            continue
        where = r['where']
        sent = 'server' if where.get('server') else 'local-fallback'
        errors = ', '.join(f'{n} {e}' for e, n in
                           r.get('fallback_errors', {}).items()) or '-'
        secs = r['seconds']
        rows.append([
            r['what'], ' / '.join(str(where.get(w, 0)) for w in WHERE),
            errors,
            f"{secs[sent]['median']:.3f} / {secs[sent]['p95']:.3f}",
            f"{secs['local']['median']:.3f} / {secs['local']['p95']:.3f}"])
    return '\n'.join(markdown_table(
        ['case', 'frames: server / local-fallback / local', 'failed offloads',
         's per offloaded frame, p50 / p95', 's per kept frame, p50 / p95'],
        rows))


#: The columns of an offload row: (record key, header).
OFFLOAD_COLUMNS = (('bbox_mAP', 'box AP'), ('bbox_mAP_50', 'box AP50'),
                   ('segm_mAP', 'mask AP'), ('segm_mAP_50', 'mask AP50'))


def _condition(name: str) -> str:
    """``'0.02'`` -> ``'beta 0.02'`` (a fog density), else the name."""
    try:
        float(name)
    except ValueError:
        return name
    return f'beta {name}'


def offload(record: dict) -> str:
    """An ``offload_eval.py`` record of one local and one server run: per
    policy the share of frames offloaded (all, and per condition), the
    pooled AP (mean +- std where the row is a mean over random draws) and
    the mean seconds per frame; then each model alone per condition, with
    the condition's mean dark-channel transmission."""
    conds = record['conditions']
    keys = [(k, h) for k, h in OFFLOAD_COLUMNS if k in record['rows'][0]]
    rows = []
    for r in record['rows']:
        cells = [r['policy'], f"{r['offload_rate']:.0%}"]
        cells += [f"{r['offloaded'][c]:.0%}" for c in conds]
        for k, _ in keys:
            std = r.get('std', {}).get(k)
            cells.append(f'{r[k]:.1f}' +
                         ('' if std is None else f' +- {std:.1f}'))
        cells.append(f"{r['seconds']:.3f}")
        rows.append(cells)
    lines = markdown_table(
        ['policy', 'offloaded'] +
        [f'offloaded, {_condition(c)}' for c in conds] +
        [h for _, h in keys] + ['mean s/frame'], rows)
    alone = []
    for c in conds:
        cells = [_condition(c), f"{record['transmission'][c]:.3f}"]
        for side in ('local', 'server'):
            cells += [f"{record['by_condition'][c][side][k]:.1f}"
                      for k, _ in keys[::2]]
        alone.append(cells)
    lines += [''] + markdown_table(
        ['condition', 'mean transmission'] +
        [f'{side} {h}' for side in ('local', 'server')
         for _, h in keys[::2]], alone)
    return '\n'.join(lines)


def offload_seeds(record: dict) -> str:
    """An ``offload_seeds.py`` table (``offload_seeds.json``: its rows
    over the seeds of the edge model, calibrated or not), in short: per
    row the share offloaded, the pooled box AP, the box AP on each
    condition's frames and the gain over random offloading at that rate,
    each mean +- std over the seeds."""

    def stat(s, scale=1.0, digits=1):
        mean, std = s['mean'] * scale, s['std'] * scale
        return f'{mean:.{digits}f} +- {std:.{digits}f}'

    conds = record['conditions']
    rows = [[r['row'], stat(r['offload_rate'], 100, 0) + ' %',
             stat(r['bbox_mAP'])] +
            [stat(r['condition_ap'][c]) for c in conds] +
            [stat(r['gain_over_random']) if 'gain_over_random' in r else '-']
            for r in record['rows']]
    return '\n'.join(markdown_table(
        ['row', 'offloaded', 'box AP'] + [f'box AP {c}' for c in conds] +
        ['gain over random'], rows))
