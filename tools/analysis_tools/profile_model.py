"""Where a detector's time goes: wall time and a ``torch.profiler`` table.

Builds a config's model with random weights (nothing downloaded), feeds it
the benchmark suite's synthetic batch (``cbnet_lab.benchmark``),
and for inference and / or one training step (forward with losses,
backward, the config's own optimiser step):

1. times ``--repeats`` un-profiled calls after ``--warmup`` (median, min);
2. profiles one more call with ``torch.profiler`` (CPU activities, plus
   CUDA where the model runs on a GPU) and reports the time of each part
   (``backbone``, ``neck``, ``rpn_head``, ``roi_head``; ``backward``,
   ``optimizer``) and the ``--top`` operators by self time.

Prints markdown and, with ``--out``, writes the same as JSON. Compare two
settings with ``--cfg-options`` (e.g. before/after an optimiser or RoI
extractor change) on the same inputs.

Usage::

    OMP_NUM_THREADS=1 python tools/analysis_tools/profile_model.py \\
        configs/cbnet/cbnet_mit-b0_nasfpn-crpn_8xb1-12e_cityscapes.py \\
        --size 256 512 --threads 1
    ... --cfg-options optim_wrapper.optimizer.foreach=False
"""
import argparse
import json
import os
import os.path as osp
import statistics
import sys
import time
from contextlib import nullcontext

from cbnet_mmdet.utils.markdown import markdown_table


#: the detector's top-level parts that get their own profiler range
PARTS = ('backbone', 'neck', 'rpn_head', 'roi_head', 'bbox_head')


def parse_args(argv=None):
    from mmengine.config import DictAction
    p = argparse.ArgumentParser(description='Profile a detector config')
    p.add_argument('config')
    p.add_argument('--size', type=int, nargs=2, default=[128, 256],
                   metavar=('H', 'W'), help='input height, width (pixels)')
    p.add_argument('--batch-size', type=int, default=1)
    p.add_argument('--num-items', type=int, default=8,
                   help='ground-truth instances per image (training)')
    p.add_argument('--mode', choices=['infer', 'train', 'both'],
                   default='both')
    p.add_argument('--warmup', type=int, default=1)
    p.add_argument('--repeats', type=int, default=3,
                   help='un-profiled timed calls (median reported)')
    p.add_argument('--top', type=int, default=15,
                   help='operators listed, by self time')
    p.add_argument('--device', default='cpu')
    p.add_argument('--threads', type=int, default=None,
                   help='torch intra-op threads; on a shared CPU use 1 (and '
                   'OMP_NUM_THREADS=1)')
    p.add_argument('--cfg-options', nargs='+', action=DictAction,
                   help='override config keys, e.g. '
                   'optim_wrapper.optimizer.foreach=False')
    p.add_argument('--proposals', choices=['fixed', 'model'],
                   default='fixed',
                   help='inference RoI heads on the benchmark\'s fixed, '
                   'realistic proposals (default) or on the random-weight '
                   'RPN\'s own')
    p.add_argument('--out', help='write the results as JSON here')
    args = p.parse_args(argv)
    for name in ('warmup', 'repeats', 'top', 'batch_size'):
        if getattr(args, name) < (0 if name == 'warmup' else 1):
            p.error(f'--{name.replace("_", "-")} must be positive')
    if min(args.size) < 32:
        p.error(f'--size {args.size} is too small (at least 32 pixels)')
    if not osp.isfile(args.config):
        p.error(f'config file not found: {args.config}')
    return args


class _Ranges:
    """Profiler ranges around the work of the detector's parts.

    Detectors call their heads through ``predict`` / ``loss`` /
    ``loss_and_predict`` as well as ``forward``, so those methods are
    wrapped on the instances (removed again by :meth:`remove`); a part's
    nested calls (``loss_and_predict`` -> ``forward``) get one range.
    """

    METHODS = ('forward', 'predict', 'loss', 'loss_and_predict')

    def __init__(self, model):
        self.patched = []
        for name in PARTS:
            module = getattr(model, name, None)
            if module is None:
                continue
            depth = [0]
            for meth in self.METHODS:
                if callable(getattr(module, meth, None)):
                    setattr(module, meth,
                            self._wrap(getattr(module, meth), name, depth))
                    self.patched.append((module, meth))

    @staticmethod
    def _wrap(fn, name, depth):
        from torch.profiler import record_function

        def wrapped(*args, **kwargs):
            if depth[0]:
                return fn(*args, **kwargs)
            depth[0] += 1
            try:
                with record_function(f'part::{name}'):
                    return fn(*args, **kwargs)
            finally:
                depth[0] -= 1

        return wrapped

    def remove(self):
        for module, meth in self.patched:
            delattr(module, meth)  # back to the class's method


def build(args):
    import torch

    from cbnet_lab import benchmark as B
    cfg = B.load_benchmark_cfg(args.config)
    if args.cfg_options:
        cfg.merge_from_dict(args.cfg_options)
    model = B.build_detector(cfg).to(args.device)
    # the benchmark suite's inputs: 8 classes, as every shipped config
    raw = B.make_batch(args.batch_size, tuple(args.size), args.num_items,
                       with_mask=B.has_mask_head(model))
    calls = {}
    if args.mode in ('infer', 'both'):
        data = B.preprocess(model, raw, False)

        fixed = args.proposals == 'fixed'

        def infer():
            model.eval()
            with torch.no_grad(), \
                    B.FixedProposals(model) if fixed else nullcontext():
                model(**data, mode='predict')

        calls['infer'] = infer
    if args.mode in ('train', 'both'):
        from mmengine.optim import build_optim_wrapper
        from torch.profiler import record_function
        wrapper = build_optim_wrapper(model, cfg.optim_wrapper)
        train_data = B.preprocess(model, raw, True)

        def train():
            model.train()
            with record_function('part::loss_forward'):
                losses = model(**train_data, mode='loss')
                loss, _ = model.parse_losses(losses)
            with record_function('part::backward'):
                wrapper.backward(loss)
            with record_function('part::optimizer'):
                wrapper.step()
                wrapper.zero_grad()

        calls['train'] = train
    return model, calls


def profile_call(fn, device, top):
    """Profile one call of ``fn``: part times and the top operators."""
    import torch
    from torch.profiler import ProfilerActivity, profile

    from cbnet_lab.benchmark import synchronize
    activities = [ProfilerActivity.CPU]
    if str(device).startswith('cuda'):
        activities.append(ProfilerActivity.CUDA)
    synchronize(device)
    start = time.perf_counter()
    with profile(activities=activities) as prof:
        fn()
        synchronize(device)
    wall = time.perf_counter() - start
    events = prof.key_averages()
    parts = {
        e.key[len('part::'):]: e.cpu_time_total / 1e3
        for e in events if e.key.startswith('part::')
    }
    ops = [e for e in events if not e.key.startswith('part::')]
    total = sum(e.self_cpu_time_total for e in ops) / 1e3
    ops.sort(key=lambda e: e.self_cpu_time_total, reverse=True)
    top_ops = [
        dict(
            name=e.key,
            calls=e.count,
            self_ms=e.self_cpu_time_total / 1e3,
            share=e.self_cpu_time_total / 1e3 / total if total else 0.)
        for e in ops[:top]
    ]
    if torch.cuda.is_available() and str(device).startswith('cuda'):
        for row, e in zip(top_ops, ops):
            row['self_cuda_ms'] = getattr(e, 'self_device_time_total',
                                          0.) / 1e3
    return dict(
        profiled_wall_s=wall,
        self_cpu_total_ms=total,
        parts_ms=parts,
        top_ops=top_ops)


def markdown(meta, results):
    lines = [
        f'`{meta["command"]}`', '',
        f'- {meta["date"]}; {meta["machine"]}; torch {meta["torch"]}, '
        f'{meta["threads"]} thread(s), OMP_NUM_THREADS='
        f'{meta["omp_num_threads"] or "unset"}; load average at start '
        f'{meta["load_start"]}', ''
    ]
    for mode, res in results.items():
        t = res['wall_s']
        lines += [
            f'### {mode}: median {statistics.median(t):.3f} s, min '
            f'{min(t):.3f} s over {len(t)} call(s); profiled call '
            f'{res["profiled_wall_s"]:.3f} s', '',
            'Parts (inclusive CPU ms): ' + ', '.join(
                f'{k} {v:.0f}' for k, v in res['parts_ms'].items()), ''
        ] + markdown_table(
            ['operator', 'calls', 'self CPU (ms)', 'share'],
            [[f'`{o["name"]}`', o['calls'], f'{o["self_ms"]:.1f}',
              f'{o["share"]:.1%}'] for o in res['top_ops']])
        lines.append('')
    return '\n'.join(lines)


def main(argv=None):
    args = parse_args(argv)
    import platform
    from datetime import datetime, timezone

    import torch

    from cbnet_lab.benchmark import time_calls
    if args.threads is not None:
        torch.set_num_threads(args.threads)
    load_start = ' / '.join(f'{v:.2f}' for v in os.getloadavg())
    model, calls = build(args)
    results = {}
    for mode, fn in calls.items():
        print(f'[profile] {mode}: {args.warmup} warm-up + {args.repeats} '
              'timed call(s) + 1 profiled', flush=True)
        times = time_calls(fn, args.repeats, args.warmup, args.device)
        ranges = _Ranges(model)
        try:
            res = profile_call(fn, args.device, args.top)
        finally:
            ranges.remove()
        res['wall_s'] = times
        results[mode] = res
    machine = (torch.cuda.get_device_name(args.device)
               if str(args.device).startswith('cuda') else
               f'{os.cpu_count()}-core {platform.machine()} CPU')
    meta = dict(
        command='python tools/analysis_tools/profile_model.py ' +
        ' '.join(sys.argv[1:] if argv is None else argv),
        date=datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC'),
        machine=machine,
        torch=torch.__version__,
        threads=torch.get_num_threads(),
        omp_num_threads=os.environ.get('OMP_NUM_THREADS'),
        load_start=load_start)
    print(markdown(meta, results))
    if args.out:
        os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
        with open(args.out, 'w') as f:
            json.dump(dict(meta=meta, results=results), f, indent=2)
    return results


if __name__ == '__main__':
    main()
