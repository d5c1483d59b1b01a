"""Forward time and peak memory of ``CBNetMiT``: ``ope`` vs ``cspe``
(and, with ``--query-chunk N``, ``cspe`` attending N query tokens at a
time: ``attn_query_chunk=N``, the same weights and result).

One fresh process per arch builds both models (the ``cspe`` one loads the
``ope`` weights; its CSPE tables are then randomised so the term is not
zero) and alternates their forwards (``ope, cspe, ope, cspe, ...`` after one
warm-up each), so load changes on a shared machine hit both alike. Peak
forward memory comes from one more, untimed forward of each, measured by
``cbnet_lab.benchmark.PeakMemory`` (resident-set peak above the
level before it, with glibc told to ``mmap`` every allocation above 64 KiB
so that freed tensors leave the resident set at once).
Inference mode (``torch.no_grad``, ``eval``), batch 1, random weights,
Mish activation, on the CPU or, with ``--device cuda``, on a GPU (each
timed forward ends in ``torch.cuda.synchronize``; memory is
``torch.cuda.max_memory_allocated`` above the level before the forward).

Usage::

    python tools/analysis_tools/benchmark_backbone.py
        [--archs b0 b2 b5] [--size 512 1024] [--runs 3]
        [--query-chunk N] [--threads N] [--device cpu|cuda]
        [--out work_dirs/benchmark_backbone.json]

Prints a markdown table (times in seconds, memory in MiB, ratio cspe/ope:
of the median times, and the median of the per-round ratios) and writes
the figures as JSON, with the machine (``cbnet_lab.report.machine_info``);
the work is ``cbnet_lab.component_benchmark``'s.
"""
import argparse
import json
import os
import os.path as osp

from cbnet_lab.component_benchmark import backbone_rows, backbone_table
from cbnet_lab.report import machine_info, machine_line


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description='CBNetMiT forward time / peak memory, ope vs cspe')
    parser.add_argument('--archs', nargs='+', default=['b0', 'b2', 'b5'])
    parser.add_argument('--pos', nargs='+', default=['ope', 'cspe'])
    parser.add_argument(
        '--size', type=int, nargs=2, default=[512, 1024],
        metavar=('H', 'W'), help='input height and width, pixels')
    parser.add_argument('--runs', type=int, default=3,
                        help='timed forwards (after one warm-up)')
    parser.add_argument('--threads', type=int, default=None,
                        help='torch intra-op threads (default: torch)')
    parser.add_argument('--query-chunk', type=int, default=None,
                        help='also measure cspe with attn_query_chunk=N')
    parser.add_argument('--device', default='cpu',
                        help="'cpu' or a CUDA device such as 'cuda'")
    parser.add_argument('--out', default='work_dirs/benchmark_backbone.json')
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    import torch
    if args.threads:  # as in the measuring processes, for the machine line
        torch.set_num_threads(args.threads)
    results = backbone_rows(
        args.archs, pos=args.pos, size=args.size, runs=args.runs,
        threads=args.threads, query_chunk=args.query_chunk,
        device=args.device)
    machine = machine_info(args.device)
    h, w = args.size
    print(f'\nCBNetMiT forward, 1x3x{h}x{w}, {args.device}: '
          f'{machine_line(machine)}; median of {args.runs}\n')
    print(backbone_table(results))
    if args.out:
        os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
        with open(args.out, 'w') as f:
            json.dump(dict(size=args.size, runs=args.runs,
                           device=args.device, machine=machine,
                           results=results),
                      f, indent=2)
        print(f'\nwritten {args.out}')


if __name__ == '__main__':
    main()
