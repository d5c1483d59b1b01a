"""Time and peak memory: ``CBNetBoundaryAwareLoss`` vs MMDet's mask BCE.

For each number of RoIs (28x28 masks, ``--num-classes`` logit channels as
an ``FCNMaskHead`` produces them) one forward + backward of

* ``bce``: MMDet's ``CrossEntropyLoss(use_mask=True)`` (the baseline),
* ``shape``: ``CBNetBoundaryAwareLoss(use_edge=False)`` (BCE + Dice),
* ``bound``: ``CBNetBoundaryAwareLoss()`` (BCE + Dice + edge term, default
  ``dist_stride=2``),
* ``bound_exact``: the same with exact distance maps (``dist_stride=1``)

is timed, forward alone and forward + backward (median and best of
``--repeats`` runs, the losses interleaved so that load changes hit all of
them alike), and the peak tensor memory of one forward + backward is
measured (torch profiler memory events on CPU,
``torch.cuda.max_memory_allocated`` on GPU; inputs not counted).

Usage::

    python tools/analysis_tools/benchmark_mask_loss.py [--rois 64 256 1024]
        [--num-classes 8] [--repeats 20] [--threads N] [--device cpu]
        [--out work_dirs/benchmark_mask_loss.json]

Prints a markdown table and writes the figures as JSON, with the machine
(``cbnet_lab.report.machine_info``); the work is
``cbnet_lab.component_benchmark``'s.
"""
import argparse
import json
import os
import os.path as osp

import torch

from cbnet_lab.component_benchmark import mask_loss_rows, mask_loss_table
from cbnet_lab.report import machine_info, machine_line


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description='Benchmark the boundary-aware mask loss against BCE')
    parser.add_argument('--rois', type=int, nargs='+', default=[64, 256, 1024])
    parser.add_argument('--size', type=int, default=28, help='mask size')
    parser.add_argument('--num-classes', type=int, default=8,
                        help='mask logit channels (Cityscapes: 8)')
    parser.add_argument('--repeats', type=int, default=20)
    parser.add_argument('--threads', type=int, default=None,
                        help='torch CPU threads (default: torch default)')
    parser.add_argument('--device', default='cpu')
    parser.add_argument('--out', default='work_dirs/benchmark_mask_loss.json')
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    rows = mask_loss_rows(args.rois, args.num_classes, args.size,
                          args.repeats, args.device)
    machine = machine_info(args.device)
    print(f'device {args.device}: {machine_line(machine)}; masks '
          f'{args.size}x{args.size}, {args.num_classes} classes, median of '
          f'{args.repeats}; forward + backward ms (x BCE, best-run x BCE), '
          'forward ms (x BCE), peak MiB')
    print(mask_loss_table(rows))
    result = dict(
        device=args.device,
        machine=machine,
        size=args.size,
        num_classes=args.num_classes,
        repeats=args.repeats,
        rows=rows)
    os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(result, f, indent=2)
    print(f'wrote {args.out}')


if __name__ == '__main__':
    main()
