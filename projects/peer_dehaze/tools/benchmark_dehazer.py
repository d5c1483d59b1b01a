"""Latency (and peak memory) of the dehazers per image.

Usage::

    OMP_NUM_THREADS=1 python \
        projects/peer_dehaze/tools/benchmark_dehazer.py \
        [--sizes 512 1024 1024 2048] [--repeats 3] [--threads 1] \
        [--device cpu] [--out work_dirs/dehaze/latency.json]

Times the learned ``CBNetAttentionDehazer`` (its small default) and
``CBNetDarkChannelPrior`` on random [0, 1] images of each H x W (batch 1,
inference, no gradients): median of ``--repeats`` calls after ``--warmup``
untimed ones, then the peak memory of one more call (``PeakMemory``). This is
the overhead a dehazer adds in front of a detector.
"""
import argparse
import json
import os
import os.path as osp

import torch
from mmdet.registry import MODELS

import cbnet_dehaze  # noqa: F401  (registers the dehazers)
from cbnet_tools.measure import PeakMemory, summarize, time_calls

DEHAZERS = dict(
    attention=dict(type='CBNetAttentionDehazer'),
    dcp=dict(type='CBNetDarkChannelPrior'))


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--sizes', type=int, nargs='+',
                        default=[512, 1024, 1024, 2048],
                        help='H W pairs, pixels')
    parser.add_argument('--dehazers', nargs='+', default=list(DEHAZERS),
                        choices=list(DEHAZERS))
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--warmup', type=int, default=1,
                        help='untimed calls first')
    parser.add_argument('--threads', type=int, default=1)
    parser.add_argument('--device', default='cpu')
    parser.add_argument('--out', help='JSON file for the results')
    return parser.parse_args(argv)


def main(argv=None) -> dict:
    args = parse_args(argv)
    if len(args.sizes) % 2:
        raise ValueError('--sizes takes H W pairs')
    torch.set_num_threads(args.threads)
    sizes = list(zip(args.sizes[::2], args.sizes[1::2]))
    results = {}
    for name in args.dehazers:
        torch.manual_seed(0)
        model = MODELS.build(DEHAZERS[name])
        model.init_weights()  # the module's own init, as in training
        model = model.to(args.device).eval()
        for h, w in sizes:
            img = torch.rand(1, 3, h, w, device=args.device)
            with torch.no_grad():
                times = time_calls(lambda: model(img), args.repeats,
                                   warmup=args.warmup, device=args.device)
                with PeakMemory(args.device) as mem:
                    model(img)
            stats = summarize(times)
            key = f'{name}@{h}x{w}'
            results[key] = dict(stats, peak_mib=mem.peak,
                                params=sum(p.numel()
                                           for p in model.parameters()))
            print(f'{key}: median {stats["median"]:.3f} s (min '
                  f'{stats["min"]:.3f}, max {stats["max"]:.3f}), peak '
                  f'memory {mem.peak} MiB', flush=True)
    if args.out:
        os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
        with open(args.out, 'w') as f:
            json.dump(dict(threads=args.threads, device=args.device,
                           results=results), f, indent=1)
    return results


if __name__ == '__main__':
    main()
