"""Forward time and peak memory of ``CBNetMiT``: ``ope`` vs ``cspe``
(and, with ``--query-chunk N``, ``cspe`` attending N query tokens at a
time: ``attn_query_chunk=N``, the same weights and result).

One subprocess per arch builds both models (the ``cspe`` one loads the
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
the figures as JSON.
"""
import argparse
import json
import os
import os.path as osp
import statistics
import subprocess
import sys

from cbnet_mmdet.utils.markdown import markdown_table


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
    parser.add_argument('--worker', help=argparse.SUPPRESS)
    return parser.parse_args(argv)


def worker(args):
    """Measure one arch, ope and cspe alternately; prints JSON lines."""
    import torch
    from mmdet.registry import MODELS

    import cbnet_mmdet  # noqa: F401
    from cbnet_lab.benchmark import (PeakMemory, set_malloc_thresholds,
                                     time_calls)
    if args.threads:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    models = {}
    for pos in args.pos:
        model = MODELS.build(
            dict(type='CBNetMiT', arch=args.worker, pos_encoding=pos,
                 init_cfg=None))
        model.init_weights()
        models[pos] = model.eval()
    if 'ope' in models and 'cspe' in models:
        models['cspe'].load_state_dict(models['ope'].state_dict(),
                                       strict=False)
    for name, p in models.get('cspe', torch.nn.Module()).named_parameters():
        if name.endswith('cspe.table'):
            torch.nn.init.normal_(p, std=0.02)
    if args.query_chunk and 'cspe' in models:
        chunked = MODELS.build(
            dict(type='CBNetMiT', arch=args.worker, pos_encoding='cspe',
                 attn_query_chunk=args.query_chunk, init_cfg=None))
        chunked.load_state_dict(models['cspe'].state_dict())
        models[f'cspe, chunk {args.query_chunk}'] = chunked.eval()
    device = torch.device(args.device)
    if device.type == 'cuda':
        torch.backends.cudnn.benchmark = False  # same kernels every round
    models = {pos: model.to(device) for pos, model in models.items()}
    x = torch.randn(1, 3, *args.size, device=device)
    stats = {pos: dict(times_s=[], peak_forward_mib=[]) for pos in models}
    set_malloc_thresholds()  # the same allocator for every timed forward
    with torch.no_grad():
        for model in models.values():  # warm-up
            model(x)
        for _ in range(args.runs):
            for pos, model in models.items():
                stats[pos]['times_s'] += time_calls(
                    lambda: model(x), 1, warmup=0, device=str(device))
        for pos, model in models.items():  # memory: one more, untimed
            with PeakMemory(str(device)) as mem:
                model(x)
            stats[pos]['peak_forward_mib'].append(mem.peak)
    for pos, model in models.items():
        print(
            json.dumps(
                dict(
                    arch=args.worker,
                    pos=pos,
                    params_m=sum(p.numel()
                                 for p in model.parameters()) / 1e6,
                    time_s=statistics.median(stats[pos]['times_s']),
                    peak_mib=max(stats[pos]['peak_forward_mib']),
                    threads=torch.get_num_threads(),
                    device=str(device),
                    **stats[pos])))


def main(argv=None):
    args = parse_args(argv)
    if args.worker:
        worker(args)
        return
    results = []
    for arch in args.archs:
        cmd = [
            sys.executable, osp.abspath(__file__), '--worker', arch, '--pos',
            *args.pos, '--size', *map(str, args.size), '--runs',
            str(args.runs)
        ]
        if args.threads:
            cmd += ['--threads', str(args.threads)]
        cmd += ['--device', args.device]
        variants = len(args.pos)
        if args.query_chunk and 'cspe' in args.pos:
            cmd += ['--query-chunk', str(args.query_chunk)]
            variants += 1
        out = subprocess.run(
            cmd, check=True, capture_output=True, text=True).stdout
        for line in out.strip().splitlines()[-variants:]:
            results.append(json.loads(line))
            print(f'done {arch} {results[-1]["pos"]}: '
                  f'{results[-1]["time_s"]:.3f} s', file=sys.stderr)
    by_key = {(r['arch'], r['pos']): r for r in results}
    for r in results:
        base = by_key.get((r['arch'], 'ope'))
        r['time_ratio'] = r['time_s'] / base['time_s'] if base else None
        r['round_time_ratio'] = statistics.median(
            a / b for a, b in zip(r['times_s'], base['times_s'])) \
            if base else None
        r['mem_ratio'] = r['peak_mib'] / base['peak_mib'] if base else None
    h, w = args.size
    if args.device == 'cpu':
        where = 'CPU'
    else:
        import torch
        where = f'{args.device}, {torch.cuda.get_device_name(args.device)}'
    print(f'\nCBNetMiT forward, 1x3x{h}x{w}, {where}, '
          f'{results[0]["threads"]} threads, median of {args.runs}\n')
    print('\n'.join(markdown_table(
        ['arch', 'pos', 'params (M)', 'time (s)', 'peak fwd mem (MiB)',
         'time / ope', 'per-round time / ope', 'mem / ope'],
        [[r['arch'], r['pos'], f'{r["params_m"]:.2f}', f'{r["time_s"]:.3f}',
          f'{r["peak_mib"]:.0f}'] +
         (['-'] * 3 if r['time_ratio'] is None else
          [f'{r["time_ratio"]:.2f}', f'{r["round_time_ratio"]:.2f}',
           f'{r["mem_ratio"]:.2f}']) for r in results])))
    if args.out:
        os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
        with open(args.out, 'w') as f:
            json.dump(dict(size=args.size, runs=args.runs,
                           device=where, results=results),
                      f, indent=2)
        print(f'\nwritten {args.out}')


if __name__ == '__main__':
    main()
