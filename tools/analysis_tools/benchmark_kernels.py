"""Each custom kernel of cbnet_mmdet against the stock op it replaces, on
one device: which one is faster THERE decides ``impl='auto'``.

* deformable convolution (the Cascade RPN's stage 2): ``gather``
  (:func:`cbnet_mmdet.models.layers.deform_conv2d`, one gather and one
  matrix product) against ``mmcv`` (``mmcv.ops.deform_conv2d``, the stock
  op) and, where it imports, ``torchvision`` (``torchvision.ops.
  deform_conv2d``, for reference). One call per FPN level of an image of
  ``--size`` (strides 4-64, ``--channels`` in and out, 3x3, offsets of a
  few pixels): inference (batch 1, no grad) and training (batch 2,
  forward + backward of input, offsets and weight).
* boundary-aware mask loss: ``fused``
  (:func:`boundary_loss_fused.boundary_loss`, one autograd Function)
  against ``autograd`` (:func:`boundary_ops.boundary_loss_autograd`, the
  same loss composed of differentiable tensor functions), forward +
  backward on ``--rois`` RoIs of 28x28 with 8 classes.

The implementations are timed in alternation (one call of each per round,
``--repeats`` rounds after a warm-up), so that load changes hit them alike;
the median and the interquartile range are reported, and the ratio of each
to the stock op. The work is ``cbnet_lab.component_benchmark``'s; the JSON
record carries the machine (``cbnet_lab.report.machine_info``).

Usage::

    python tools/analysis_tools/benchmark_kernels.py --device cuda
        [--size 512 1024] [--size 1024 2048] [--channels 256]
        [--rois 64 256 1024] [--repeats 20] [--threads N]
        [--out work_dirs/benchmark_kernels.json]
"""
import argparse
import json
import os
import os.path as osp
import sys

import torch

from cbnet_lab.component_benchmark import kernel_rows, kernel_table
from cbnet_lab.report import machine_info, machine_line


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--device', default='cpu')
    parser.add_argument('--size', type=int, nargs=2, action='append',
                        help='image size H W (repeatable); default 512 1024')
    parser.add_argument('--channels', type=int, default=256)
    parser.add_argument('--rois', type=int, nargs='+', default=[64, 256, 1024])
    parser.add_argument('--repeats', type=int, default=20)
    parser.add_argument('--threads', type=int, default=None)
    parser.add_argument('--out', default='work_dirs/benchmark_kernels.json')
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    try:
        rows = kernel_rows(args.size or [[512, 1024]], args.channels,
                           args.rois, args.repeats, args.device,
                           on_rows=lambda new: print(kernel_table(new),
                                                     flush=True))
    except (ValueError, ImportError) as err:
        sys.exit(str(err))
    machine = machine_info(args.device)
    os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(dict(device=args.device, machine=machine,
                       repeats=args.repeats, rows=rows), f, indent=1)
    print(kernel_table(rows))
    print(f'machine: {machine_line(machine)}\nwritten: {args.out}')


if __name__ == '__main__':
    main()
