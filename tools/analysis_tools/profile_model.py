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

Prints markdown and, with ``--out``, writes the same as JSON (the machine,
``cbnet_lab.report.machine_info``, under ``meta.machine``); the work is
``cbnet_lab.profiling``'s. Compare two settings with ``--cfg-options``
(e.g. before/after an optimiser or RoI extractor change) on the same
inputs.

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
import sys
from datetime import datetime, timezone

from cbnet_lab import profiling
from cbnet_lab.report import machine_info


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


def build(args):
    """The model and its calls, as the command line asks."""
    return profiling.build(
        args.config, size=args.size, batch_size=args.batch_size,
        num_items=args.num_items, mode=args.mode, device=args.device,
        cfg_options=args.cfg_options, proposals=args.proposals)


def main(argv=None):
    args = parse_args(argv)
    import torch
    if args.threads is not None:
        torch.set_num_threads(args.threads)
    machine = machine_info(args.device)  # load average at the start
    model, calls = build(args)
    results = profiling.profile(model, calls, args.warmup, args.repeats,
                                args.device, args.top)
    meta = dict(
        command='python tools/analysis_tools/profile_model.py ' +
        ' '.join(sys.argv[1:] if argv is None else argv),
        date=datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC'),
        machine=machine)
    print(profiling.markdown(meta, results))
    if args.out:
        os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
        with open(args.out, 'w') as f:
            json.dump(dict(meta=meta, results=results), f, indent=2)
    return results


if __name__ == '__main__':
    main()
