"""Markdown tables printed from committed records that the comparison
harness does not write: the speed, memory and FLOPs records of
``benchmark.py`` and of the lent devices (``docs/benchmarks/*.json``),
the kernel and backbone timings (``benchmark_kernels.py``,
``benchmark_backbone.py``), the proposal statistics of
``proposal_quality.py`` (``docs/accuracy/*.json``), the model index
(``configs/**/metafile.yml``), the serving records
(``docs/serving/``: :mod:`cbnet_lab.serving_tables`) and the README's
results table (a spec over the comparison records:
:mod:`cbnet_lab.results_summary`).

``tools/misc/record_table.py KIND RECORD ...`` prints one of them; the
docs' generated regions name that command (:mod:`cbnet_lab.doc_tables`),
so a table a page shows is what its record holds. Every kind reads JSON
or YAML only (no model is built, nothing is measured); medians are of the
recorded rounds, ratios between models measured in one process.
"""
import json
import statistics
from typing import Callable, Dict, List, Optional, Sequence

from cbnet_tools.markdown import markdown_table

from . import serving_tables
from .results_summary import results_summary

#: Readable names of the models and positional encodings of the records.
LABELS = {
    'b2': 'CBNet MiT-B2',
    'b5': 'CBNet MiT-B5',
    'cbnet_mit-b0': 'CBNet MiT-B0',
    'cbnet_mit-b2': 'CBNet MiT-B2',
    'cbnet_mit-b5': 'CBNet MiT-B5',
    'cascade-mask-rcnn_swin-s': 'Cascade Mask R-CNN Swin-S',
    'swin-s': 'Cascade Mask R-CNN Swin-S',
    'swin-s_k300': 'Cascade Mask R-CNN Swin-S, 300 test proposals',
}


def label(name: str) -> str:
    """The readable name of a record's model (the name itself if none)."""
    return LABELS.get(name, name)


def load(path: str):
    """A JSON record, or a YAML one (``.yml`` / ``.yaml``: a metafile)."""
    with open(path, encoding='utf-8') as f:
        if path.endswith(('.yml', '.yaml')):
            import yaml
            return yaml.safe_load(f)
        return json.load(f)


def part(record, key: Optional[str]):
    """The part of ``record`` at a dotted ``key`` (``gpu.1024``); the whole
    record without one.

    Raises:
        KeyError: a step of the key the record does not hold (the keys it
            does hold are named).
    """
    if not key:
        return record
    node = record
    for step in key.split('.'):
        if not isinstance(node, dict) or step not in node:
            held = sorted(node) if isinstance(node, dict) else []
            raise KeyError(f'the record holds no {key!r} (at {step!r}: '
                           f'{held})')
        node = node[step]
    return node


def _size(side: str) -> str:
    """``'512'`` -> ``'512x1024'`` (the records' cells name the height)."""
    return f'{side}x{2 * int(side)}'


# -- like for like (device_like_for_like.json) -------------------------------


def _lfl_cell(times: dict, size: str, threads: str, model: str,
              proposals: int) -> Optional[tuple]:
    """(seconds of ``model``, seconds of Swin-S) at equal ``proposals``:
    medians of the rounds of the one process that timed both."""
    name = model if proposals == 300 else f'{model}_k{proposals}'
    swin = 'swin-s_k300' if proposals == 300 else 'swin-s'
    for key in (f's{size}_t{threads}',
                f's{size}_t{threads}_{model}_k{proposals}'):
        cell = times.get(key, {})
        if name in cell and swin in cell:
            return (statistics.median(cell[name]),
                    statistics.median(cell[swin]))
    return None


def like_for_like_ratio(record: dict, model: str, size: str, threads: str,
                        proposals: int) -> float:
    """The median inference time of ``model`` (``b2``, ``b5``; ``swin-s``
    is 1 by definition) over Swin-S's at equal ``proposals``, input
    height ``size`` and ``threads``, from the one process that timed both.

    Raises:
        KeyError: the record has no such cell.
    """
    times = record['inference_round_times_s']
    cell = _lfl_cell(times, size, threads,
                     'b5' if model == 'swin-s' else model, proposals)
    if cell is None:
        raise KeyError(f'the like-for-like record has no cell for {model} '
                       f'at {_size(size)}, {threads} threads, {proposals} '
                       'proposals')
    return cell[1] / cell[1] if model == 'swin-s' else cell[0] / cell[1]


def _lfl_rows(times: dict) -> List[tuple]:
    """(size, threads, proposals) of every CPU cell of the record, in
    order: sizes, then threads, then 300 before 1000."""
    keys = set()
    for key in times:
        if not key.startswith('s'):
            continue
        bits = key[1:].split('_')
        keys.add((int(bits[0]), int(bits[1][1:])))
    return [(str(s), str(t), k) for s, t in sorted(keys) for k in (300, 1000)]


def like_for_like(record: dict, table: str = 'ratios') -> str:
    """The like-for-like tables of ``docs/benchmarks/device_like_for_like
    .json`` (CBNet MiT-B2 and MiT-B5 each timed in alternation with Cascade
    Mask R-CNN Swin-S at equal test proposals).

    Args:
        record (dict): The record.
        table (str): ``ratios`` (inference time over Swin-S's per input
            and threads), ``latency`` (the median times and the ratios),
            ``gpu`` (the same on the GPU), ``training`` (a training step:
            time and peak memory over Swin-S's) or ``gflops`` (counted
            arithmetic).
    """
    times = record['inference_round_times_s']
    if table in ('ratios', 'latency'):
        rows = []
        for size, threads, k in _lfl_rows(times):
            b2 = _lfl_cell(times, size, threads, 'b2', k)
            b5 = _lfl_cell(times, size, threads, 'b5', k)
            if not (b2 and b5):
                continue
            where = (f'{_size(size)}, {threads} thread'
                     f'{"s" if threads != "1" else ""}')
            swin = f'{b2[1]:.2f}' if b2[1] == b5[1] else \
                f'{b2[1]:.2f} / {b5[1]:.2f}'
            rows.append((where, k, b2, b5, swin))
        if table == 'latency':
            return '\n'.join(markdown_table(
                ['input, threads', 'test proposals (each)',
                 'CBNet MiT-B2 (s)', 'CBNet MiT-B5 (s)',
                 "Swin-S (s; B2's run / B5's run where two)", 'B2 / Swin-S',
                 'B5 / Swin-S'],
                [[where, k, f'{b2[0]:.2f}', f'{b5[0]:.2f}', swin,
                  f'{b2[0] / b2[1]:.2f}', f'{b5[0] / b5[1]:.2f}']
                 for where, k, b2, b5, swin in rows]))
        pairs = {}
        for where, k, b2, b5, _ in rows:
            pairs.setdefault(where, {})[k] = (b2[0] / b2[1], b5[0] / b5[1])
        return '\n'.join(markdown_table(
            ['input, threads', 'MiT-B2 / Swin-S, 300 / 1000 proposals',
             'MiT-B5 / Swin-S, 300 / 1000 proposals'],
            [[where, f'{p[300][0]:.2f} / {p[1000][0]:.2f}',
              f'{p[300][1]:.2f} / {p[1000][1]:.2f}']
             for where, p in pairs.items() if 300 in p and 1000 in p]))
    if table == 'gpu':
        rows = []
        for key, cell in times.items():
            if not key.startswith('gpu_'):
                continue
            for k in (300, 1000):
                suffix = '' if k == 300 else '_k1000'
                swin = statistics.median(
                    cell['swin-s_k300' if k == 300 else 'swin-s'])
                b2 = statistics.median(cell['b2' + suffix])
                b5 = statistics.median(cell['b5' + suffix])
                rows.append([key[len('gpu_'):], k, f'{1e3 * b2:.0f}',
                             f'{1e3 * b5:.0f}', f'{1e3 * swin:.0f}',
                             f'{b2 / swin:.2f}', f'{b5 / swin:.2f}'])
        rows.sort(key=lambda r: (int(r[0].split('x')[0]), r[1]))
        return '\n'.join(markdown_table(
            ['input', 'test proposals (each)', 'CBNet MiT-B2 (ms)',
             'CBNet MiT-B5 (ms)', 'Swin-S (ms)', 'B2 / Swin-S',
             'B5 / Swin-S'], rows))
    if table == 'training':
        runs = record['training']

        def step(run, model):
            result = runs[run]['results'][model]
            return statistics.median(result['step_s']), result['peak_mib']

        ref = 'cascade-mask-rcnn_swin-s'
        models = [m for m in ('cbnet_mit-b2', 'cbnet_mit-b5', ref)
                  if f'train_t1_{m}' in runs]
        out = []
        for m in models:
            t1, mem = step(f'train_t1_{m}', m)
            t2, _ = step(f'train_t2_{m}', m)
            gpu, gmem = step('train_gpu', m)
            r1, rmem = step(f'train_t1_{ref}', ref)
            r2, _ = step(f'train_t2_{ref}', ref)
            rg, rgmem = step('train_gpu', ref)
            out.append([label(m), f'{t1:.1f}', f'{t1 / r1:.2f}', f'{t2:.1f}',
                        f'{t2 / r2:.2f}', f'{mem / 1024:.1f}',
                        f'{mem / rmem:.2f}', f'{gpu:.2f}', f'{gpu / rg:.2f}',
                        f'{gmem / 1024:.1f}'])
        return '\n'.join(markdown_table(
            ['model', 'CPU step, 1 thread (s)', '/ Swin-S',
             'CPU step, 2 threads (s)', '/ Swin-S',
             'peak resident set, 1 thread (GiB)', '/ Swin-S', 'GPU step (s)',
             '/ Swin-S', 'GPU peak allocated (GiB)'], out))
    if table == 'gflops':
        values = record['gflops']['values']
        models, sizes = [], []
        for key in values:
            model, size = key.rsplit(' ', 1)
            if model not in models:
                models.append(model)
            if size not in sizes:
                sizes.append(size)
        ref = 'cascade-mask-rcnn_swin-s'
        last = sizes[-1]
        out = []
        for m in models:
            cells = [f'{values[f"{m} {s}"]["features"]:.1f} / '
                     f'{values[f"{m} {s}"]["predict"]:.1f}' for s in sizes]
            mine, theirs = values[f'{m} {last}'], values[f'{ref} {last}']
            out.append([label(m)] + cells + [
                f'{mine["features"] / theirs["features"]:.2f} / '
                f'{mine["predict"] / theirs["predict"]:.2f}'])
        return '\n'.join(markdown_table(
            ['GFLOPs, backbone + neck / whole inference'] + sizes +
            [f'{last} / Swin-S'], out))
    raise ValueError(f'like-for-like: no table {table!r} (ratios, latency, '
                     'gpu, training, gflops)')


# -- benchmark.py's scaling with input size ----------------------------------


def scaling(record: dict, reference: Optional[str] = None) -> str:
    """Latency and peak memory against input size, from a ``benchmark.py``
    record (``scaling.sizes``): one row per model, its growth from the
    smallest to the largest input and its time over ``reference``'s at
    each size (default: the Swin-S model of the record)."""
    sizes = record['scaling']['sizes']
    if reference is None:
        reference = next((m for m in sizes if 'swin-s' in m), None)
    first = next(iter(sizes.values()))
    heads = [f'{c["size"][0]}x{c["size"][1]}' for c in first]
    out = []
    for model, cells in sizes.items():
        row = [label(model)] + [f'{c["seconds"]:.2f} / {c["peak_mib"]:.0f}'
                                for c in cells]
        row.append(f'{cells[-1]["seconds"] / cells[0]["seconds"]:.1f}x')
        if reference in sizes:
            ref = sizes[reference]
            row.append(', '.join(f'{a["seconds"] / b["seconds"]:.2f}'
                                 for a, b in zip(cells, ref)))
        out.append(row)
    head = (['model'] + [f'{h} (s / MiB)' for h in heads] +
            [f'growth {heads[0]} -> {heads[-1]}'])
    if reference in sizes:
        head.append(f'/ {label(reference)} at each size')
    return '\n'.join(markdown_table(head, out))


# -- kernels (benchmark_kernels.py) ------------------------------------------


def _stock_rows(rows: List[dict]) -> Dict[tuple, dict]:
    """The stock row (``vs_stock`` 1) of each (kernel, setting)."""
    return {(r['kernel'], r['setting']): r for r in rows
            if abs(r['vs_stock'] - 1.0) < 1e-12}


def kernels(record: dict) -> str:
    """Each kernel of a ``benchmark_kernels.py`` record against the stock
    op it replaces: median (IQR) in ms, and its time over the stock op's;
    one row per implementation that is not the stock one."""
    rows = record['rows']
    stock = _stock_rows(rows)
    out = []
    for r in rows:
        ref = stock.get((r['kernel'], r['setting']))
        if ref is None or r is ref:
            continue
        out.append([r['kernel'], r['setting'], r['impl'],
                    f'{r["median_ms"]:.2f} ({r["iqr_ms"]:.2f})', ref['impl'],
                    f'{ref["median_ms"]:.2f} ({ref["iqr_ms"]:.2f})',
                    f'{r["vs_stock"]:.2f}'])
    return '\n'.join(markdown_table(
        ['kernel', 'setting', 'implementation', 'ms, median (IQR)', 'stock',
         'stock ms, median (IQR)', '/ stock'], out))


def kernel_threads(record: dict) -> str:
    """One ``benchmark_kernels.py`` record per thread count (``{threads:
    record}``): each implementation's median ms at each count and its
    speed-up from the fewest threads to the most."""
    counts = sorted(record, key=int)
    counts = [c for c in counts if isinstance(record[c], dict) and
              'rows' in record[c]]
    first = record[counts[0]]['rows']
    out = []
    for r in first:
        cells = []
        for c in counts:
            match = [x for x in record[c]['rows']
                     if (x['kernel'], x['setting'], x['impl']) ==
                     (r['kernel'], r['setting'], r['impl'])]
            cells.append(match[0]['median_ms'] if match else None)
        have = [v for v in cells if v is not None]
        out.append([r['kernel'], r['setting'], r['impl']] +
                   ['-' if v is None else f'{v:.2f}' for v in cells] +
                   [f'{have[0] / have[-1]:.1f}x'])
    return '\n'.join(markdown_table(
        ['kernel', 'setting', 'implementation'] +
        [f'{c} thread{"s" if c != "1" else ""} (ms)' for c in counts] +
        [f'{counts[0]} -> {counts[-1]} threads'], out))


# -- MiT backbones (benchmark_backbone.py) -----------------------------------


def backbone(record: dict) -> str:
    """A ``benchmark_backbone.py`` record (or ``{name: record}``, several
    sizes): one row per backbone and input, the time and peak memory of
    each positional encoding, and the last one's over the second's."""
    records = [record] if 'results' in record else list(record.values())
    out, encodings = [], []
    for rec in records:
        for r in rec['results']:
            if r['pos'] not in encodings:
                encodings.append(r['pos'])
    cuda = any(str(r.get('device', '')).startswith('cuda')
               for rec in records for r in rec['results'])
    unit = 'ms' if cuda else 's'
    for rec in records:
        h, w = rec['size']
        by_arch = {}
        for r in rec['results']:
            by_arch.setdefault(r['arch'], {})[r['pos']] = r
        for arch, by_pos in by_arch.items():
            cells = []
            for pos in encodings:
                r = by_pos.get(pos)
                if r is None:
                    cells.append('-')
                    continue
                t = r['time_s'] * (1e3 if cuda else 1)
                digits = 1 if t >= 10 else 2
                cells.append(f'{t:.{digits}f} / {r["peak_mib"]:.0f}')
            a, b = (by_pos.get(encodings[-1]), by_pos.get(encodings[1])) \
                if len(encodings) > 2 else (None, None)
            ratio = '-' if not (a and b) else \
                f'{a["time_s"] / b["time_s"]:.2f}, ' \
                f'{a["peak_mib"] / b["peak_mib"]:.2f}'
            out.append([f'MiT-{arch.upper()}, {h}x{w} (median of '
                        f'{rec["runs"]})'] + cells + [ratio])
    head = (['backbone, input'] +
            [f'`{p}` {unit} / MiB' for p in encodings])
    head.append(f'`{encodings[-1]}` / `{encodings[1]}`: time, memory'
                if len(encodings) > 2 else '-')
    return '\n'.join(markdown_table(head, out))


def backbone_threads(record: dict) -> str:
    """One ``benchmark_backbone.py`` record per thread count (``{threads:
    record}``): each encoding's forward time at each count and the
    speed-up from the fewest threads to the most."""
    counts = sorted(record, key=int)
    first = record[counts[0]]
    h, w = first['size']
    out = []
    for r in first['results']:
        times = []
        for c in counts:
            match = [x for x in record[c]['results']
                     if (x['arch'], x['pos']) == (r['arch'], r['pos'])]
            times.append(match[0]['time_s'] if match else None)
        have = [t for t in times if t is not None]
        out.append([f'MiT-{r["arch"].upper()} `{r["pos"]}`'] +
                   ['-' if t is None else f'{t:.3f}' for t in times] +
                   [f'{have[0] / have[-1]:.1f}x'])
    return '\n'.join(markdown_table(
        [f'forward, {h}x{w}'] +
        [f'{c} thread{"s" if c != "1" else ""} (s)' for c in counts] +
        [f'{counts[0]} -> {counts[-1]} threads'], out))


# -- proposal_quality.py -----------------------------------------------------


def proposals(record: dict) -> str:
    """What each model's RPN hands its RoI heads (a ``proposal_quality.py``
    record): recall of the ground truth at each IoU, mean best IoU, and
    the share of proposals that are positives at each IoU."""
    results = record['results']
    first = next(iter(results.values()))
    recall = list(first['recall'])
    share = list(first['positive_share'])
    return '\n'.join(markdown_table(
        ['model', 'proposals / image'] + [f'recall@{t}' for t in recall] +
        ['mean best IoU'] + [f'proposals IoU>={t}' for t in share],
        [[name, f'{r["proposals_per_image"]:.0f}'] +
         [f'{r["recall"][t]:.3f}' for t in recall] +
         [f'{r["mean_best_iou"]:.3f}'] +
         [f'{r["positive_share"][t]:.3f}' for t in share]
         for name, r in results.items()]))


def proposals_seeds(record: dict) -> str:
    """:func:`proposals` over seeds: the runs named ``NAME sN`` (one per
    seed, as ``proposal_quality.py --names`` gives them) grouped by
    ``NAME``, each figure in percent as mean +- std (sample std) over the
    seeds."""
    groups: Dict[str, List[dict]] = {}
    for name, result in record['results'].items():
        stem, _, seed = name.rpartition(' s')
        groups.setdefault(stem if stem and seed.isdigit() else name,
                          []).append(result)
    first = next(iter(record['results'].values()))
    recall = list(first['recall'])
    share = list(first['positive_share'])

    def cell(values):
        mean = statistics.mean(values)
        std = statistics.stdev(values) if len(values) > 1 else 0.0
        return f'{100 * mean:.1f} +- {100 * std:.1f}'

    return '\n'.join(markdown_table(
        ['model (%)', 'seeds'] + [f'recall@{t}' for t in recall] +
        ['mean best IoU'] + [f'proposals IoU>={t}' for t in share],
        [[name, len(runs)] +
         [cell([r['recall'][t] for r in runs]) for t in recall] +
         [cell([r['mean_best_iou'] for r in runs])] +
         [cell([r['positive_share'][t] for r in runs]) for t in share]
         for name, runs in groups.items()]))


# -- benchmark.py's inference table (benchmark.json) --------------------------


def benchmark(record: dict) -> str:
    """The inference table of a ``benchmark.py`` record (``benchmark.json``:
    ``meta``, ``results``, ``scaling``), as ``benchmark.md`` gives it: its
    tables only, without the run's notes (command, clock, load)."""
    from .model_benchmark import markdown
    md = markdown(record['meta'], record['results'],
                  record.get('scaling', {}))
    blocks, block = [], []
    for line in md.splitlines():
        if line.startswith('|'):
            block.append(line)
        elif block:
            blocks.append(block)
            block = []
    if block:
        blocks.append(block)
    return '\n\n'.join('\n'.join(b) for b in blocks)


# -- the model index (metafile.yml) ------------------------------------------


def model_index(records: Sequence[dict],
                datasets: Sequence[str] = (),
                metrics: Sequence[str] = ()) -> str:
    """The results of one or more metafiles (MMDetection's model index,
    what ``mim search`` reads): one row per model and dataset, the
    metrics as columns; a model without results gets one row of ``-``.

    Args:
        records (Sequence[dict]): The loaded metafiles.
        datasets (Sequence[str]): Keep the results whose dataset contains
            one of these (and the models that have one); all by default.
        metrics (Sequence[str]): The metric columns (default: every metric
            of the rows, in order of appearance).
    """
    rows, columns = [], []
    for record in records:
        for model in record.get('Models', []):
            epochs = (model.get('Metadata') or {}).get('Epochs', '-')
            by_dataset = {}
            for result in model.get('Results') or []:
                name = result['Dataset']
                if datasets and not any(d in name for d in datasets):
                    continue
                by_dataset.setdefault(name, {}).update(result['Metrics'])
            if not by_dataset and not model.get('Results') and \
                    not datasets:
                by_dataset['-'] = {}
            for name, values in by_dataset.items():
                columns += [m for m in values if m not in columns]
                rows.append((f'`{model["Config"]}`', epochs, name, values))
    columns = list(metrics) or columns
    return '\n'.join(markdown_table(
        ['config', 'epochs', 'dataset'] + columns,
        [[config, epochs, name] + [
            '-' if values.get(m) is None else f'{values[m]}'
            for m in columns] for config, epochs, name, values in rows]))


#: The kinds of table ``tools/misc/record_table.py`` prints, by name.
KINDS: Dict[str, Callable] = {
    'like-for-like': like_for_like,
    'scaling': scaling,
    'kernels': kernels,
    'kernel-threads': kernel_threads,
    'backbone': backbone,
    'backbone-threads': backbone_threads,
    'proposals': proposals,
    'proposals-seeds': proposals_seeds,
    'benchmark': benchmark,
    'model-index': model_index,
    'results-summary': results_summary,
    'edge-speed': serving_tables.edge_speed,
    'load-test': serving_tables.load_test,
    'fallback': serving_tables.fallback,
    'offload': serving_tables.offload,
    'offload-seeds': serving_tables.offload_seeds,
}
#: The kinds that read several records (the rest read one).
MULTI_RECORD = frozenset({'model-index', 'load-test'})
