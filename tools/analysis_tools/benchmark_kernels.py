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
to the stock op.

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
import platform
import sys
from typing import Callable, Dict, List

import torch

from cbnet_lab.benchmark import summarize, time_calls
from cbnet_mmdet.models.layers.cbnet_deform_conv2d import \
    deform_conv2d as gather_deform_conv2d
from cbnet_mmdet.models.losses import boundary_loss_fused, boundary_ops
from cbnet_mmdet.utils.markdown import markdown_table

STRIDES = (4, 8, 16, 32, 64)


def stock_deform_ops() -> Dict[str, Callable]:
    """The stock deformable convolutions that import here."""
    ops = {}
    try:
        from mmcv.ops import deform_conv2d as mmcv_op
        ops['mmcv'] = lambda x, off, w: mmcv_op(x, off, w, 1, 1, 1, 1, 1)
    except (ImportError, OSError):
        pass
    try:
        from torchvision.ops import deform_conv2d as tv_op

        def tv(x, off, w):
            # torchvision's offsets are (dy, dx) per tap as mmcv's
            return tv_op(x, off, w, padding=1)

        ops['torchvision'] = tv
    except (ImportError, OSError, RuntimeError):
        pass
    return ops


def deform_inputs(size, channels, batch, device, grad, seed=0):
    """One (x, offset, weight) per FPN level of a ``size`` image."""
    gen = torch.Generator().manual_seed(seed)
    levels = []
    for stride in STRIDES:
        h, w = -(-size[0] // stride), -(-size[1] // stride)
        x = torch.randn(batch, channels, h, w, generator=gen)
        off = 2 * torch.randn(batch, 18, h, w, generator=gen)
        wt = 0.05 * torch.randn(channels, channels, 3, 3, generator=gen)
        levels.append([t.to(device).requires_grad_(grad) for t in
                       (x, off, wt)])
    return levels


def deform_case(op, levels, grad):
    """One Cascade-RPN stage-2 pass over all levels (with backward)."""

    def run():
        if not grad:
            with torch.no_grad():
                for x, off, w in levels:
                    op(x, off, w)
            return
        total = sum(op(x, off, w).float().square().mean()
                    for x, off, w in levels)
        total.backward()

    return run


def loss_inputs(rois, device, seed=0):
    gen = torch.Generator().manual_seed(seed)
    logits = torch.randn(rois * 8, 28, 28, generator=gen)
    targets = (torch.rand(rois, 28, 28, generator=gen) > 0.5).float()
    index = torch.arange(rois) * 8 + torch.randint(0, 8, (rois, ),
                                                   generator=gen)
    return (logits.to(device).requires_grad_(), targets.to(device),
            index.to(device))


def loss_case(fn, logits, targets, index):

    def run():
        fn(logits, targets, index=index, dist_stride=2).mean().backward()

    return run


def interleaved(cases: Dict[str, Callable], repeats: int,
                device: str) -> Dict[str, List[float]]:
    """``repeats`` rounds, one timed call of each case per round."""
    times = {name: [] for name in cases}
    for fn in cases.values():  # one untimed warm-up: kernels, allocator
        time_calls(fn, 0, warmup=1, device=device)
    for _ in range(repeats):
        for name, fn in cases.items():
            times[name] += time_calls(fn, 1, warmup=0, device=device)
    return times


def rows_of(kernel, setting, times, stock):
    base = summarize(times[stock])['median']
    rows = []
    for name, values in times.items():
        s = summarize(values)
        rows.append(dict(kernel=kernel, setting=setting, impl=name,
                         median_ms=1e3 * s['median'], iqr_ms=1e3 * s['iqr'],
                         vs_stock=s['median'] / base))
    return rows


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
    sizes = args.size or [[512, 1024]]
    for h, w in sizes:
        if -(-min(h, w) // STRIDES[-1]) < 3:
            # mmcv's kernel refuses maps smaller than the 3x3 kernel
            sys.exit(f'--size {h} {w}: the stride-{STRIDES[-1]} level would '
                     'be smaller than 3x3, which mmcv\'s kernel (the '
                     f'baseline) refuses; use at least {2 * STRIDES[-1] + 1} '
                     'px on each side')
    device = args.device
    stock = stock_deform_ops()
    if 'mmcv' not in stock:
        sys.exit('mmcv.ops.deform_conv2d does not import: the stock op is '
                 'needed as the baseline')
    rows = []
    for size in sizes:
        for grad, batch in ((False, 1), (True, 2)):
            levels = deform_inputs(size, args.channels, batch, device, grad)
            ops = dict(gather=gather_deform_conv2d_3x3, **stock)
            cases = {n: deform_case(op, levels, grad) for n, op in ops.items()}
            setting = (f'{size[0]}x{size[1]}, C={args.channels}, batch '
                       f'{batch}, ' + ('fwd+bwd' if grad else 'inference'))
            rows += rows_of('deform conv (CRPN stage 2, P2-P6)', setting,
                            interleaved(cases, args.repeats, device), 'mmcv')
            print(to_markdown(rows[-len(ops):]), flush=True)
    for rois in args.rois:
        inputs = loss_inputs(rois, device)
        cases = {
            'fused': loss_case(boundary_loss_fused.boundary_loss, *inputs),
            'autograd': loss_case(boundary_ops.boundary_loss_autograd,
                                  *inputs),
        }
        rows += rows_of('boundary loss', f'{rois} RoIs 28x28, fwd+bwd',
                        interleaved(cases, args.repeats, device), 'autograd')
        print(to_markdown(rows[-2:]), flush=True)
    machine = dict(device=device, torch=torch.__version__,
                   threads=torch.get_num_threads(), host=platform.node(),
                   cpu=platform.processor() or platform.machine())
    if device.startswith('cuda'):
        machine['gpu'] = torch.cuda.get_device_name(device)
    if hasattr(os, 'getloadavg'):
        machine['loadavg'] = os.getloadavg()
    os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(dict(machine=machine, repeats=args.repeats, rows=rows), f,
                  indent=1)
    print(to_markdown(rows))
    print(f'machine: {machine}\nwritten: {args.out}')


def to_markdown(rows: List[dict]) -> str:
    return '\n'.join(markdown_table(
        ['kernel', 'setting', 'impl', 'median ms', 'IQR ms', 'x stock'],
        [[r['kernel'], r['setting'], r['impl'], f"{r['median_ms']:.2f}",
          f"{r['iqr_ms']:.2f}", f"{r['vs_stock']:.2f}"] for r in rows]))


def gather_deform_conv2d_3x3(x, off, w):
    return gather_deform_conv2d(x, off, w, padding=(1, 1))


if __name__ == '__main__':
    main()
