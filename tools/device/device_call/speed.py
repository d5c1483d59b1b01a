"""The speed step: like for like, fp32 then AMP (the dry run: on the CPU,
the AMP command lines checked)."""
import argparse
import json
import os.path as osp
import shlex
import time

from .runner import BOXES, DRY_BOXES, Runner

#: Like-for-like speed (docs/benchmarks.md): B2, B5 and Swin-S at 300 test
#: proposals each (the CBNet configs' count; Swin-S overridden).
SPEED_MODELS = ['cbnet_mit-b2', 'cbnet_mit-b5', 'cascade-mask-rcnn_swin-s']
SPEED_OVERRIDES = ['--model-cfg', 'cascade-mask-rcnn_swin-s',
                   'model.test_cfg.rpn.max_per_img=300']
#: (pass name, what it measures, its size on the device); AMP passes add
#: ``--amp``; the dry run keeps what each pass measures at a tiny size.
SPEED_PASSES = [
    ('infer', ['--batch-sizes', '1', '--no-train'],
     ['--size', '1024', '2048', '--repeats', '10', '--warmup', '3']),
    ('train', ['--no-infer'],
     ['--size', '512', '1024', '--train-batch-size', '2', '--repeats', '5',
      '--warmup', '2']),
]
DRY_SPEED = ['--size', '64', '128', '--train-batch-size', '2',
             '--repeats', '1', '--warmup', '0']


def speed_commands(args, mmcv_cuda: bool):
    """(name, argv) of the speed passes; the dry run's on the CPU."""
    tool = osp.join('tools', 'analysis_tools', 'benchmark.py')
    base = [args.python, tool, '--no-flops', '--scale-sizes',
            '--scale-items', '--threads', '1']
    out = osp.join(args.work_dir, 'speed')
    if args.dry_run:
        return [(f'{p}_fp32_cpu', base + ['--models'] + args.speed_models +
                 overrides(args) + what + DRY_SPEED + ['--device', 'cpu',
                 '--out-dir', osp.join(out, f'{p}_fp32_cpu')])
                for p, what, _ in SPEED_PASSES]
    if not mmcv_cuda:
        # the fallback: no detector runs on the GPU; the MiT trunks do
        trunk = osp.join('tools', 'analysis_tools', 'benchmark_backbone.py')
        return [('trunk_fp32', [args.python, trunk, '--device', 'cuda',
                                '--archs', 'b2', 'b5', '--pos', 'cspe',
                                '--size', '1024', '2048', '--runs', '10',
                                '--out', osp.join(out, 'trunk_fp32',
                                                  'benchmark_backbone.json')])]
    # training first (AMP training is what no device measured yet), each
    # precision pair back to back on the same card
    cmds = []
    for p, what, size in SPEED_PASSES[::-1]:
        for amp in (False, True):
            name = f'{p}_{"amp" if amp else "fp32"}'
            cmds.append((name, base + ['--models'] + args.speed_models +
                         overrides(args) + what + size + ['--device', 'cuda'] +
                         (['--amp'] if amp else []) +
                         ['--out-dir', osp.join(out, name)]))
    return cmds


def overrides(args):
    """Swin-S at 300 test proposals, where it is measured."""
    name = SPEED_OVERRIDES[1]
    return SPEED_OVERRIDES if name in args.speed_models else []


def amp_check_command(args):
    """The dry run cannot run AMP (CUDA only): one process checks that
    benchmark.py accepts the device run's AMP command lines."""
    dev = argparse.Namespace(**dict(vars(args), dry_run=False))
    lines = [cmd[2:] for _, cmd in speed_commands(dev, True)
             if '--amp' in cmd]
    code = ('import json, runpy, sys; parse = runpy.run_path(sys.argv[1])'
            '["parse_args"]\n'
            'for argv in json.loads(sys.argv[2]): parse(argv)\n'
            'print(len(json.loads(sys.argv[2])), "AMP command lines '
            'accepted")')
    tool = osp.join('tools', 'analysis_tools', 'benchmark.py')
    return [args.python, '-c', code, tool, json.dumps(lines)], lines


def step_speed(r: Runner, env, mmcv_cuda) -> dict:
    t0, runs, made = time.time(), [], {}
    box = DRY_BOXES['speed_pass'] if r.args.dry_run else BOXES['speed_pass']
    for name, cmd in speed_commands(r.args, mmcv_cuda):
        if r.left() < 30:
            runs.append(dict(command=name, skipped='no time left'))
            continue
        res = r.run(cmd, min(box, r.left() - 20), f'speed_{name}', env)
        res['pass'] = name
        runs.append(res)
        made[name] = speed_figures(r.work, name)
    if r.args.dry_run:
        cmd, lines = amp_check_command(r.args)
        res = r.run(cmd, 120, 'speed_amp_check', env)
        res.update({'pass': 'AMP command lines checked (AMP needs CUDA)',
                    'checked': [' '.join(map(shlex.quote, x))
                                for x in lines]})
        runs.append(res)
    bad = [x for x in runs if x.get('rc') not in (0, None)]
    status = 'ok' if not bad else 'partial' if len(bad) < len(runs) \
        else 'failed'
    note = '' if mmcv_cuda or r.args.dry_run else \
        'mmcv without CUDA ops: only the MiT trunks were timed on the GPU'
    return r.step('speed', status, time.time() - t0, note, runs=runs,
                  figures=made)


def speed_figures(work, name) -> dict:
    """Medians and peaks per model from a pass's benchmark.json."""
    path = osp.join(work, 'speed', name, 'benchmark.json')
    try:
        with open(path) as f:
            rec = json.load(f)
    except (OSError, ValueError):
        return {}
    out = {}
    for model, res in (rec.get('results') or {}).items():
        row = {}
        for bs, inf in (res.get('inference') or {}).items():
            row[f'infer_b{bs}_median_s'] = inf['seconds']['median']
            row[f'infer_b{bs}_img_per_s'] = inf['images_per_s']
            row[f'infer_b{bs}_peak_mib'] = inf['peak_mib']
        if res.get('train_step'):
            row['train_median_s'] = res['train_step']['seconds']['median']
            row['train_peak_mib'] = res['train_step']['peak_mib']
        out[model] = row
    return out
