"""Everything a lent GPU machine should measure, in one time-boxed call.

Run by ``tools/device/run_all.sh`` (docs/benchmarks.md, "One call on a
lent GPU"). Standard library only: on a fresh device machine nothing of the
OpenMMLab stack is installed until the set-up step has run.

Steps, in order, each in its own process group under its own time box (a
step that overruns is killed, recorded as ``timed out`` and the next one
starts; what it finished is kept):

``setup``
    Installs the carried wheels (``--wheels``: mmengine, mmdet and the
    packages the device image lacks) into ``<work>/site`` and builds mmcv
    2.1.0 from its carried sdist with CUDA ops for the GPU's architecture
    only (``TORCH_CUDA_ARCH_LIST``, ``MAX_JOBS`` = the cores). If that build
    fails or overruns its box, mmcv is built with its CPU ops only (the
    fallback): every mmcv op (RoIAlign, NMS, deformable convolution, sigmoid
    focal loss) then has no CUDA kernel, so no detector can run on the GPU;
    the speed step then times the pure-PyTorch MiT trunk on the GPU and the
    harness trains on the CPU cores. A carried mmcv wheel (built by an
    earlier call, which returns it in ``$OUT``) is installed instead of
    building; an mmcv with CUDA ops already in ``<work>/site`` (a second
    call on a still-warm machine) is kept.
``tests``
    The CUDA-only tests (``pytest -m cuda`` on the test files that hold
    them; tests/conftest.py marks every test skipped with 'needs CUDA').
``speed``
    Like for like, CBNet MiT-B2 / MiT-B5 against Cascade Mask R-CNN Swin-S
    (all at 300 test proposals), fp32 then AMP: inference at 1024x2048,
    batch 1 (latency, img/s, peak memory) and a training step at 512x1024,
    batch 2 (time, peak memory), ``tools/analysis_tools/benchmark.py``.
``harness``
    Each set of ``--sets`` (any set file of ``configs/experiments/``) with
    ``tools/analysis_tools/compare_recipes.py`` at its device budget (its
    preset's, seeds 0 1 2: the plan of ``device_call/plans.py``, read from
    the set's file), every run (recipe x seed) in its own worker process
    at once on the one GPU (``--jobs N``), one torch thread each; then ``--report-only`` tabulates the runs that finished,
    so a set cut off by its box still has its record.

``--dry-run`` runs every step on the CPU with a tiny budget (nothing is
installed or built; tiny generated data where ``--data`` lacks a set's).

The steps are the modules of ``tools/device/device_call/``: ``runner``
(time boxes, records, the packed output), ``stack`` (set-up),
``cuda_tests``, ``speed``, ``harness`` over ``plans`` (each set's plan
from its file), ``prepare`` (``--prepare``).

Output in ``--out`` (``$OUT`` on the device machine; the device tool brings
back 8 files at most): ``summary.json`` (machine, each step's status,
seconds, box, commands, and what it measured), ``run_all.log`` (this
script's log) and ``records.tar.gz`` (the harness records in the harness's
format, the benchmark records, the test report and every step's log, no
checkpoints), plus the built mmcv wheel as ``mmcv-wheel.partNN`` (cat them
together) when it fits the device tool's limits.
"""
import argparse
import json
import os
import os.path as osp
import shutil
import signal
import sys
import time
from datetime import datetime, timezone

sys.path.insert(0, osp.dirname(osp.abspath(__file__)))
from device_call import stack  # noqa: E402
from device_call.cuda_tests import step_tests  # noqa: E402
from device_call.harness import step_harness  # noqa: E402
from device_call.plans import set_names  # noqa: E402
from device_call.prepare import prepare  # noqa: E402
from device_call.runner import (ROOT, Runner, Stopped, _stop,  # noqa: E402
                                git_commit, machine_text, mmcv_has_cuda,
                                pack, probe, python_env, stack_ok)
from device_call.speed import SPEED_MODELS, step_speed  # noqa: E402

#: The harness sets run by default: the pretrained-trunk set on real fog
#: (its data and the trunk's checkpoint fit one call with the wheels;
#: ``coco_street`` is the second call's, ``--sets coco_street``).
DEFAULT_SETS = ['realfog_pretrained']

#: Wheels the device image lacks (its package list: /work/.library/device
#: KINDS.md, "Python packages already there"), for Python 3.12, x86_64;
#: ``--prepare`` downloads them into ``--wheels``. mmcv comes as its sdist.
WHEELS = ['mmengine==0.10.7', 'mmdet==3.3.0', 'addict==2.4.0',
          'yapf==0.43.0', 'platformdirs', 'termcolor', 'terminaltables',
          'pycocotools>=2.0.8', 'shapely', 'setuptools>=77,<80.9']
MMCV = 'mmcv==2.1.0'


def setup_plan(args) -> dict:
    """What the set-up step installs from ``--wheels``."""
    return stack.setup_plan(args.wheels, WHEELS, MMCV)


def step_setup(r: Runner) -> dict:
    return stack.step_setup(r, setup_plan(r.args))


# ----------------------------------------------------------------- main ---
def parse_args(argv=None):
    p = argparse.ArgumentParser(
        description=__doc__.split('\n\n')[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog='Steps and outputs: see the module docstring and '
        'docs/benchmarks.md.')
    p.add_argument('--out', default=os.environ.get('OUT'),
                   help='where the results go (default: $OUT, else '
                   '<work-dir>/out)')
    p.add_argument('--work-dir', default=osp.join(ROOT, 'work_dirs',
                                                  'device'),
                   help='installed site, builds, records (ignored by git, '
                   'so a second call on a warm machine finds them)')
    p.add_argument('--steps', default='setup,tests,speed,harness',
                   help='comma-separated, in this order: setup, tests, '
                   'speed, harness')
    p.add_argument('--sets', nargs='+', default=DEFAULT_SETS,
                   help='harness sets, any set file of configs/experiments/ '
                   f'(default {DEFAULT_SETS}; known: {set_names()})')
    p.add_argument('--budget', type=float, default=None,
                   help='seconds for the whole call (default 540: the '
                   'device tool allows 600 a command; the dry run 1800)')
    p.add_argument('--wheels', default=osp.join(ROOT, '.whl'),
                   help='carried wheels and the mmcv sdist')
    p.add_argument('--data', default=os.environ.get(
        'CBNET_DEVICE_DATA', osp.join(ROOT, 'data', 'device')),
                   help="folder holding each set's data folder "
                   '(dawn_fog, ...); $CBNET_DEVICE_DATA')
    p.add_argument('--pretrained', default=None,
                   help='carried cache of pretrained trunks, exported as '
                   '$CBNET_PRETRAINED_DIR')
    p.add_argument('--speed-models', nargs='+', default=SPEED_MODELS,
                   help='benchmark.py models of the speed step (default: '
                   'the like-for-like three)')
    p.add_argument('--max-procs', type=int, default=32,
                   help='harness processes at most per set')
    p.add_argument('--python', default=sys.executable)
    p.add_argument('--dry-run', action='store_true',
                   help='every step on the CPU, tiny budget, nothing '
                   'installed')
    p.add_argument('--prepare', action='store_true',
                   help='here, not on the device: download the wheels, '
                   'copy the data, print the run call and its size')
    p.add_argument('--data-src', default=None,
                   help='--prepare: where the sets\' data folders are')
    p.add_argument('--refresh', action='store_true',
                   help='--prepare: download the wheels again')
    args = p.parse_args(argv)
    steps = [s.strip() for s in args.steps.split(',') if s.strip()]
    bad = [s for s in steps if s not in ('setup', 'tests', 'speed',
                                         'harness')]
    if bad:
        p.error(f'--steps: unknown {bad}')
    args.steps = steps
    known = set_names()
    for name in args.sets:
        if name not in known:
            p.error(f'--sets: unknown {name!r}; the set files '
                    f'(configs/experiments/): {known}')
    if args.budget is None:
        args.budget = 1800 if args.dry_run else 540
    if args.out is None:
        args.out = osp.join(args.work_dir, 'out')
    args.work_dir = osp.abspath(args.work_dir)
    args.out = osp.abspath(args.out)
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.prepare:
        return prepare(args, WHEELS, MMCV)
    r = Runner(args)
    signal.signal(signal.SIGTERM, _stop)
    date = datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M:%S UTC')
    r.log(f'start {date}; steps {args.steps}; budget {args.budget:.0f} s'
          f'{"; DRY RUN (CPU, tiny budget)" if args.dry_run else ""}')
    summary = dict(date=date, dry_run=args.dry_run, budget_s=args.budget,
                   machine=machine_text(), argv=sys.argv[1:],
                   commit=git_commit(), sets=args.sets, steps=r.steps)
    env = python_env(args, None if args.dry_run else
                     osp.join(args.work_dir, 'site'))
    mmcv_cuda = False
    try:
        if 'setup' in args.steps:
            rec = step_setup(r)
            env = rec.pop('env')
            info = rec.get('probe') or probe(args, env)
        else:
            info = probe(args, env)
        summary['software'] = info
        mmcv_cuda = mmcv_has_cuda(info)
        if not stack_ok(info):
            r.log('the OpenMMLab stack does not import: later steps skipped')
            for s in args.steps:
                if s != 'setup':
                    r.step(s, 'skipped', 0, 'no working stack')
        else:
            if 'tests' in args.steps:
                step_tests(r, env)
            if 'speed' in args.steps:
                step_speed(r, env, mmcv_cuda)
            if 'harness' in args.steps:
                henv = env
                if not mmcv_cuda and not args.dry_run:
                    # CPU-only mmcv ops: MMEngine would put the models on
                    # the GPU, where RoIAlign / NMS have no kernel
                    henv = dict(env, CUDA_VISIBLE_DEVICES='')
                step_harness(r, henv)
    except Stopped as err:
        r.log(f'stopped by {err}: the step running was killed')
        summary['stopped'] = str(err)
    finally:
        summary['seconds'] = round(time.time() - r.start, 1)
        summary['mmcv_cuda_ops'] = mmcv_cuda
        with open(osp.join(args.out, 'summary.json'), 'w') as f:
            json.dump(summary, f, indent=1)
        shutil.copy(osp.join(args.out, 'summary.json'),
                    osp.join(args.work_dir, 'summary.json'))
        pack(r)
        r.log(f'done in {summary["seconds"]:.0f} s: '
              + ', '.join(f"{s['name']} {s['status']}" for s in r.steps))
    failed = [s for s in r.steps if s['status'] == 'failed']
    return 1 if failed or 'stopped' in summary else 0


if __name__ == '__main__':
    sys.exit(main())
