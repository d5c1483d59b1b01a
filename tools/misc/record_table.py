"""Print a Markdown table from a committed speed, kernel, backbone,
proposal, serving or model-index record, or the README's results summary
(what compare_recipes.py does not tabulate).

Usage::

    python tools/misc/record_table.py like-for-like \
        docs/benchmarks/device_like_for_like.json --table ratios
    python tools/misc/record_table.py scaling \
        docs/benchmarks/scaling_like_for_like.json
    python tools/misc/record_table.py kernels \
        docs/benchmarks/kernels_cuda_h100.json
    python tools/misc/record_table.py backbone \
        docs/benchmarks/device_h200_chunk_threads.json --key gpu
    python tools/misc/record_table.py model-index \
        configs/cbnet/metafile.yml configs/baselines/metafile.yml
    python tools/misc/record_table.py load-test \
        docs/serving/realfog/load/pass2_r1_b1.json \
        docs/serving/realfog/load/pass2_r2_b1.json --names "1, 1" "2, 1"
    python tools/misc/record_table.py results-summary \
        docs/results_summary.yml

Kinds (cbnet_lab/record_tables.py): ``like-for-like`` (``--table ratios``,
``latency``, ``gpu``, ``training`` or ``gflops``), ``scaling``,
``kernels``, ``kernel-threads``, ``backbone``, ``backbone-threads``,
``benchmark`` (``benchmark.py``'s inference table), ``proposals``,
``proposals-seeds`` (runs named ``NAME sN`` as mean +- std over seeds),
``model-index`` (``--datasets``, ``--metrics``), the serving records'
``edge-speed`` (``--reference``), ``load-test`` (several records,
``--names``), ``fallback``, ``offload`` and ``offload-seeds`` (an
``offload_seeds.json``, in short; cbnet_lab/serving_tables.py),
and ``results-summary`` (the README's results table from its spec,
cbnet_lab/results_summary.py). ``--key a.b`` takes the part of a JSON
record at that dotted key. The table is printed and, with ``--out-dir``,
written there as ``record_table.md`` (what the docs' generated regions
read: tools/misc/update_doc_tables.py).
"""
import argparse
import os
import os.path as osp
import sys

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))


def parse_args(argv=None):
    sys.path.insert(0, ROOT)
    from cbnet_lab.record_tables import KINDS
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('kind', choices=sorted(KINDS))
    parser.add_argument('records', nargs='+',
                        help='the JSON record (model-index: metafiles)')
    parser.add_argument('--key', help='a dotted key: the part of the '
                        'record to tabulate (e.g. gpu.1024)')
    parser.add_argument('--table', default='ratios',
                        help='like-for-like: ratios, latency, gpu, '
                        'training or gflops')
    parser.add_argument('--reference',
                        help='scaling, edge-speed: the model of the ratio '
                        'column (default: the record\'s Swin-S; '
                        'edge-speed: the recorded command\'s)')
    parser.add_argument('--names', nargs='+',
                        help='load-test: a name per record (default: 0, '
                        '1, ...)')
    parser.add_argument('--datasets', nargs='+', default=[],
                        help='model-index: keep the results whose dataset '
                        'contains one of these')
    parser.add_argument('--metrics', nargs='+', default=[],
                        help='model-index: the metric columns')
    parser.add_argument('--out-dir',
                        help='also write the table there as '
                        'record_table.md')
    args = parser.parse_args(argv)
    from cbnet_lab.record_tables import MULTI_RECORD
    if args.kind not in MULTI_RECORD and len(args.records) > 1:
        parser.error(f'{args.kind} reads one record')
    if args.names and len(args.names) != len(args.records):
        parser.error(f'--names gives {len(args.names)} names for '
                     f'{len(args.records)} records')
    return args


def table(args) -> str:
    """The table ``args`` ask for."""
    from cbnet_lab import record_tables as rt
    if args.kind == 'model-index':
        return rt.model_index([rt.load(p) for p in args.records],
                              args.datasets, args.metrics)
    if args.kind == 'load-test':
        return rt.KINDS['load-test'](
            [rt.part(rt.load(p), args.key) for p in args.records],
            args.names)
    record = rt.part(rt.load(args.records[0]), args.key)
    if args.kind == 'like-for-like':
        return rt.like_for_like(record, args.table)
    if args.kind in ('scaling', 'edge-speed'):
        return rt.KINDS[args.kind](record, args.reference)
    if args.kind == 'results-summary':  # its records' paths: from here
        return rt.results_summary(record, os.getcwd())
    return rt.KINDS[args.kind](record)


def main(argv=None) -> str:
    args = parse_args(argv)
    md = table(args) + '\n'
    if args.out_dir:
        os.makedirs(args.out_dir, exist_ok=True)
        with open(osp.join(args.out_dir, 'record_table.md'), 'w') as f:
            f.write(md)
    print(md, end='')
    return md


if __name__ == '__main__':
    main()
