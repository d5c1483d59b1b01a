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

Prints a markdown table and writes the figures as JSON.
"""
import argparse
import json
import os
import os.path as osp
import platform
import time

import numpy as np
import torch
from mmdet.registry import MODELS
from torch.profiler import ProfilerActivity, profile

import cbnet_mmdet  # noqa: F401  (registers the loss)
from cbnet_mmdet.utils.markdown import markdown_table

LOSSES = {
    'bce': dict(type='CrossEntropyLoss', use_mask=True, loss_weight=1.0),
    'shape': dict(type='CBNetBoundaryAwareLoss', use_edge=False),
    'bound': dict(type='CBNetBoundaryAwareLoss'),  # dist_stride=2
    'bound_exact': dict(type='CBNetBoundaryAwareLoss', dist_stride=1),
}


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


def make_inputs(num_rois, args, seed=0):
    gen = torch.Generator().manual_seed(seed)
    pred = torch.randn(num_rois, args.num_classes, args.size, args.size,
                       generator=gen)
    target = (torch.rand(num_rois, args.size, args.size, generator=gen) >
              0.5).float()
    label = torch.randint(0, args.num_classes, (num_rois, ), generator=gen)
    return (pred.to(args.device).requires_grad_(), target.to(args.device),
            label.to(args.device))


def step(loss_fn, pred, target, label, device='cpu'):
    """One forward + backward; returns the seconds of the forward and of
    the whole step."""
    pred.grad = None
    sync(device)
    start = time.perf_counter()
    loss = loss_fn(pred, target, label)
    sync(device)
    forward = time.perf_counter() - start
    loss.backward()
    sync(device)
    return forward, time.perf_counter() - start


def sync(device):
    if device.startswith('cuda'):
        torch.cuda.synchronize()


def time_losses(num_rois, args):
    """Median and best seconds of one forward + backward, and median of
    the forward alone, per loss.

    The losses run interleaved, so that a change of machine load hits all
    of them alike; the best run is the least disturbed by other processes.
    """
    inputs = make_inputs(num_rois, args)
    fns = {name: MODELS.build(cfg) for name, cfg in LOSSES.items()}
    times = {name: [] for name in fns}
    forward = {name: [] for name in fns}
    for name, fn in fns.items():  # warm-up
        step(fn, *inputs, device=args.device)
    for _ in range(args.repeats):
        for name, fn in fns.items():
            fwd, total = step(fn, *inputs, device=args.device)
            forward[name].append(fwd)
            times[name].append(total)
    return ({name: float(np.median(v))
             for name, v in times.items()},
            {name: float(np.min(v))
             for name, v in times.items()},
            {name: float(np.median(v))
             for name, v in forward.items()})


def peak_memory(name, num_rois, args):
    """Peak tensor memory (MiB) allocated during one forward + backward.

    CPU: replay of the torch profiler's per-op allocation/free events in
    time order; GPU: ``torch.cuda.max_memory_allocated``. Memory that
    exists before the step (inputs, the loss module) is not counted; the
    gradient of ``pred`` is.
    """
    fn = MODELS.build(LOSSES[name])
    inputs = make_inputs(num_rois, args)
    step(fn, *inputs)  # warm-up
    inputs[0].grad = None
    if args.device.startswith('cuda'):
        torch.cuda.synchronize()
        torch.cuda.reset_peak_memory_stats()
        base = torch.cuda.memory_allocated()
        step(fn, *inputs)
        torch.cuda.synchronize()
        return (torch.cuda.max_memory_allocated() - base) / 2**20
    with profile(activities=[ProfilerActivity.CPU],
                 profile_memory=True) as prof:
        step(fn, *inputs)
    events = sorted((e for e in prof.events()
                     if e.self_cpu_memory_usage != 0),
                    key=lambda e: e.time_range.start)
    usage = np.cumsum([e.self_cpu_memory_usage for e in events])
    return float(usage.max(initial=0)) / 2**20


def main(argv=None):
    args = parse_args(argv)
    from cbnet_lab.benchmark import set_malloc_thresholds

    # glibc's steady allocator for every timed call (as benchmark.py):
    # otherwise the 25 MiB logits gradient is mapped and page-faulted anew
    # in a varying share of the steps, the main source of the spread
    set_malloc_thresholds()
    if args.threads:
        torch.set_num_threads(args.threads)
    rows = []
    for num_rois in args.rois:
        times, best, forward = time_losses(num_rois, args)
        mem = {name: peak_memory(name, num_rois, args) for name in LOSSES}
        rows.append(
            dict(
                rois=num_rois,
                time_ms={k: v * 1e3
                         for k, v in times.items()},
                best_time_ms={k: v * 1e3
                              for k, v in best.items()},
                peak_mem_mib=mem,
                time_ratio_vs_bce={
                    k: times[k] / times['bce']
                    for k in times
                },
                forward_time_ms={k: v * 1e3
                                 for k, v in forward.items()},
                forward_time_ratio_vs_bce={
                    k: forward[k] / forward['bce']
                    for k in forward
                },
                best_time_ratio_vs_bce={
                    k: best[k] / best['bce']
                    for k in best
                }))
    print(f'device: {args.device}, threads: {torch.get_num_threads()}, '
          f'{platform.processor() or platform.machine()}, '
          f'masks {args.size}x{args.size}, {args.num_classes} classes, '
          f'median of {args.repeats}; forward + backward ms (x BCE, '
          'best-run x BCE), forward ms (x BCE), peak MiB')
    names = list(LOSSES)
    print('\n'.join(markdown_table(['RoIs'] + names, [[r['rois']] + [
        f"{r['time_ms'][n]:.2f} ({r['time_ratio_vs_bce'][n]:.2f}, "
        f"{r['best_time_ratio_vs_bce'][n]:.2f}); "
        f"fwd {r['forward_time_ms'][n]:.2f} "
        f"({r['forward_time_ratio_vs_bce'][n]:.2f}); "
        f"{r['peak_mem_mib'][n]:.1f} MiB" for n in names
    ] for r in rows])))
    result = dict(
        device=args.device,
        threads=torch.get_num_threads(),
        cpu_count=os.cpu_count(),
        size=args.size,
        num_classes=args.num_classes,
        repeats=args.repeats,
        torch=torch.__version__,
        rows=rows)
    os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(result, f, indent=2)
    print(f'wrote {args.out}')


if __name__ == '__main__':
    main()
