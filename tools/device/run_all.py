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
    Each set of ``--sets`` with ``tools/analysis_tools/compare_recipes.py``
    at its device budget (:data:`SETS`), every run (recipe x seed) in its
    own worker process at once on the one GPU (``--jobs N``), one torch
    thread each; then ``--report-only`` tabulates the runs that finished,
    so a set cut off by its box still has its record.

``--dry-run`` runs every step on the CPU with a tiny budget (nothing is
installed or built; tiny generated data where ``--data`` lacks a set's).

Output in ``--out`` (``$OUT`` on the device machine; the device tool brings
back 8 files at most): ``summary.json`` (machine, each step's status,
seconds, box, commands, and what it measured), ``run_all.log`` (this
script's log) and ``records.tar.gz`` (the harness records in the harness's
format, the benchmark records, the test report and every step's log, no
checkpoints), plus the built mmcv wheel as ``mmcv-wheel.partNN`` (cat them
together) when it fits the device tool's limits.
"""
import argparse
import glob
import json
import os
import os.path as osp
import platform
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tarfile
import time
import xml.etree.ElementTree as ET
from datetime import datetime, timezone

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))

#: The harness sets run by default: the pretrained-trunk set on real fog
#: (its data and the trunk's checkpoint fit one call with the wheels;
#: ``coco_street`` is the second call's, ``--sets coco_street``).
DEFAULT_SETS = ['realfog_pretrained']


def _dry_args(only=None, seeds=('0', ), scale=(160, 96)):
    """A dry run's compare_recipes.py arguments: 2 iterations of the row
    ``only`` (every row when None) for ``seeds`` at ``scale`` (w, h),
    batch 2, no worker processes."""
    rows = ['--only', only] if only is not None else []
    return (['--seeds', *seeds, '--iters', '2', '--warmup-iters', '1',
             '--batch-size', '2', '--num-workers', '0'] + rows +
            ['--img-scale', str(scale[0]), str(scale[1]), '--cfg-options',
             'test_dataloader.num_workers=0',
             'test_dataloader.persistent_workers=False'])


def _dawn_fog_set(dry_only):
    """A set on DAWN's fog at its preset's budget, 3 seeds, whose dry run
    trains the one row ``dry_only`` for 2 iterations on a tiny VOC
    folder."""
    return dict(
        data='dawn_fog',
        args=['--seeds', '0', '1', '2'],
        needs=[],
        dry_args=_dry_args(dry_only),
        dry_needs=[],
        tiny='cbnet_tools.synthetic.voc_folder:tiny_fog_folder')


#: Per set: ``data`` (its folder under ``--data``), optionally
#: ``transfer`` (a second folder it is also tested on, --transfer-root,
#: with ``transfer_tiny`` for the dry run) and ``make`` (the command that
#: makes ``data`` on the machine when it is not carried), ``args`` (the
#: compare_recipes.py budget on the device), ``needs`` (files, relative to
#: the repository, the set's recipes read: carried with the call),
#: ``dry_args`` / ``dry_needs`` (the dry run's tiny budget) and ``tiny``
#: (``module:function(root)`` writing tiny data of the set's kind, for a
#: dry run without the real data), optionally ``tiny_weights``
#: (``module:function(folder)`` writing stand-ins of the pretrained files
#: the set loads, for a dry run without ``--pretrained``).
SETS = {
    'realfog': dict(
        data='dawn_fog',
        args=['--seeds', '0', '1', '2', '--iters', '200',
              '--warmup-iters', '10', '--batch-size', '4'],
        needs=['work_dirs/dehaze/dehazer_attention_1xb4-200it_'
               'cityscapes-like/iter_200.pth'],
        dry_args=['--seeds', '0', '1', '--iters', '2', '--warmup-iters',
                  '1', '--batch-size', '2', '--num-workers', '0',
                  '--only', 'YOLOX-Tiny', '--cfg-options',
                  'train_dataloader.dataset.pipeline.2.scale=(160,96)',
                  'test_dataloader.dataset.pipeline.2.scale=(160,96)',
                  'test_dataloader.num_workers=0',
                  'test_dataloader.persistent_workers=False'],
        dry_needs=[],
        tiny='cbnet_tools.synthetic.voc_folder:tiny_fog_folder'),
    # The pretrained-trunk sets at their CPU presets' budgets (12 epochs
    # on DAWN, 36 on COCO street, batch 2, 640x480:
    # cbnet_lab/recipe_comparison.py), so the device's
    # seeds merge with the CPU's into one table (--restore); a longer
    # budget is a new table: add --iters N. They need the converted
    # trunk: --pretrained DIR (CBNET_PRETRAINED_DIR=DIR python
    # tools/model_converters/fetch_pretrained.py mobilenet_v2).
    'realfog_pretrained': dict(
        data='dawn_fog',
        args=['--seeds', '0', '1', '2'],
        needs=[],
        dry_args=_dry_args('YOLOX-Tiny', seeds=('0', '1')),
        dry_needs=[],
        tiny='cbnet_tools.synthetic.voc_folder:tiny_fog_folder'),
    # the parts of the two real-fog recipes (configs/pretrained/parts/),
    # same data and budget: --sets realfog_pretrained_parts
    'realfog_pretrained_parts': _dawn_fog_set(
        'Cascade R-CNN +IoU .5/.7/.9, trunk lr x1'),
    # the trunk at the full lr on the two question recipes
    # (configs/pretrained/finetune/): --sets realfog_pretrained_finetune
    'realfog_pretrained_finetune': _dawn_fog_set(
        'Cascade R-CNN, trunk lr x1'),
    # the stock cascade and the revised CBNet on EfficientNet-Lite0
    # (configs/pretrained/trunks/; --pretrained DIR must also hold
    # fetch_pretrained.py efficientnet_lite0's file):
    # --sets realfog_pretrained_trunks
    'realfog_pretrained_trunks': _dawn_fog_set(
        'Cascade R-CNN, EfficientNet-Lite0, trunk lr x1'),
    # NAS-FPN on GroupNorm beside BatchNorm and FPN
    # (configs/pretrained/neck/): --sets realfog_pretrained_neck
    'realfog_pretrained_neck': _dawn_fog_set(
        'CBNet revised, NAS-FPN GN, trunk lr x1'),
    # a COCO-pretrained YOLOX-Nano on real fog (configs/yolox_coco/) at
    # its CPU preset's budget, so the device's seeds merge with the CPU's
    # (--restore); --pretrained DIR must hold the two files of
    # fetch_pretrained.py yolox_nano. The dry run writes seeded stand-ins
    # of both (``tiny_weights``) when --pretrained is not given.
    'realfog_coco': dict(
        _dawn_fog_set('YOLOX-Nano COCO, fine-tuned'),
        tiny_weights='cbnet_tools.synthetic.yolox_checkpoints:'
        'tiny_yolox_nano'),
    # the converted split with the photos copied (a link would travel as
    # a link): tools/dataset_converters/coco_street.py SRC
    # data/device/coco_street --copy
    'coco_street': dict(
        data='coco_street',
        args=['--seeds', '0', '1', '2'],
        needs=[],
        dry_args=_dry_args(scale=(256, 128)),
        dry_needs=[],
        tiny=None),
    # the transfer experiment (fog_transfer set): trained on the clear COCO
    # street photos (the coco_street folder as above), every run also tested
    # on DAWN's real fog (``transfer``: a second carried folder, passed as
    # --transfer-root). Only DAWN's 65 val photos are tested, so --prepare
    # copies those and every XML (the seeded split reads the XMLs' names:
    # :data:`VAL_ONLY`), which keeps the call under 64 MiB. Its ceiling
    # is the realfog_pretrained record (compare_recipes.py --ceiling).
    # Its clear-only rows train as the coco_street set's rows: when that
    # set ran earlier in the same call (``--sets coco_street
    # fog_transfer``), its work dir is passed as --weights-from and those
    # runs are tested, not trained again.
    'fog_transfer': dict(
        data='coco_street', transfer='dawn_fog_val',
        weights_from='coco_street',
        args=['--seeds', '0', '1', '2'],
        needs=[],
        # one row at 256x128, tested on the tiny fog folder too
        dry_args=_dry_args('Cascade Mask R-CNN, clear', scale=(256, 128)),
        dry_needs=[],
        tiny=None,
        transfer_tiny='cbnet_tools.synthetic.voc_folder:tiny_fog_folder'),
    # generated -> real: trained on the generated
    # benchmark (made on the device by ``make``: the generator is
    # deterministic, so nothing is carried but DAWN), tested on DAWN too
    'fog_generated_to_real': dict(
        data='cityscapes_like_bench', transfer='dawn_fog_val',
        make=['tools/misc/generate_cityscapes_like.py', '{path}',
              '--preset', 'bench', '--nproc', '{nproc}', '--convert'],
        args=['--seeds', '0', '1', '2'],
        needs=[],
        dry_args=_dry_args('Cascade Mask R-CNN, generated clear',
                           scale=(256, 128)),
        dry_needs=[],
        tiny='cbnet_tools.synthetic.cityscapes_like:tiny_converted',
        transfer_tiny='cbnet_tools.synthetic.voc_folder:tiny_fog_folder'),
}

#: Transfer folders that --prepare fills with the val photos of the
#: seeded split only (and every XML): folder -> (the full folder it is
#: copied from, the split's val_fraction and seed as the configs set
#: them: configs/realfog/_base_/voc-fog_box.py).
VAL_ONLY = {'dawn_fog_val': ('dawn_fog', 0.3, 0)}

#: Wheels the device image lacks (its package list: /work/.library/device
#: KINDS.md, "Python packages already there"), for Python 3.12, x86_64;
#: ``--prepare`` downloads them into ``--wheels``. mmcv comes as its sdist.
WHEELS = ['mmengine==0.10.7', 'mmdet==3.3.0', 'addict==2.4.0',
          'yapf==0.43.0', 'platformdirs', 'termcolor', 'terminaltables',
          'pycocotools>=2.0.8', 'shapely', 'setuptools>=77,<80.9']
MMCV = 'mmcv==2.1.0'

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

#: Time boxes (seconds) of the real run; the harness gets what is left.
BOXES = dict(install=90, build=420, fallback_build=180, tests=90,
             speed_pass=60, report=60, pack=30, make_data=120)
DRY_BOXES = dict(install=30, build=0, fallback_build=0, tests=120,
                 speed_pass=300, report=60, pack=10)
#: A harness set given less than this is skipped (seconds).
MIN_HARNESS_S = dict(real=120, dry=30)
#: The device tool brings back files of at most 16 MiB.
PART_BYTES = 15 * 2**20


class Stopped(Exception):
    """This script was sent SIGTERM (a caller's time limit)."""


def _stop(signum, frame):
    raise Stopped(f'signal {signum}')


class Runner:
    """Runs commands in their own process group under a time box and
    keeps the record of each step."""

    def __init__(self, args):
        self.args = args
        self.work = args.work_dir
        self.start = time.time()
        self.deadline = self.start + args.budget
        self.steps = []
        os.makedirs(osp.join(self.work, 'logs'), exist_ok=True)
        os.makedirs(args.out, exist_ok=True)
        self.log_file = open(osp.join(args.out, 'run_all.log'), 'a')

    def log(self, text):
        line = f'[run_all {time.strftime("%H:%M:%S")}] {text}'
        print(line, flush=True)
        self.log_file.write(line + '\n')
        self.log_file.flush()

    def left(self) -> float:
        return self.deadline - time.time()

    def run(self, cmd, box, log_name, env=None, cwd=ROOT) -> dict:
        """Run ``cmd`` for at most ``box`` seconds; its output goes to
        ``<work>/logs/<log_name>.log``. Returns ``rc``, ``seconds``,
        ``timed_out``, ``command``."""
        path = osp.join(self.work, 'logs', f'{log_name}.log')
        text = ' '.join(shlex.quote(c) for c in cmd)
        self.log(f'$ {text}  (box {box:.0f} s, log {path})')
        t0 = time.time()
        with open(path, 'ab') as out:
            proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=out,
                                    stderr=subprocess.STDOUT,
                                    start_new_session=True)
            timed_out = False
            try:
                rc = proc.wait(timeout=max(box, 1))
            except subprocess.TimeoutExpired:
                timed_out = True
                rc = kill_group(proc)
            except BaseException:
                # stopped (SIGTERM, Ctrl-C): the step's processes go too,
                # they run in their own session and would outlive this one
                kill_group(proc, grace=3)
                raise
        took = time.time() - t0
        self.log(f'  rc {rc}{" (timed out)" if timed_out else ""}, '
                 f'{took:.1f} s')
        return dict(command=text, rc=rc, seconds=round(took, 1),
                    timed_out=timed_out, log=osp.relpath(path, self.work))

    def step(self, name, status, seconds, note='', **extra):
        rec = dict(name=name, status=status, seconds=round(seconds, 1),
                   note=note, **extra)
        self.steps.append(rec)
        self.log(f'step {name}: {status} in {seconds:.1f} s'
                 + (f' ({note})' if note else ''))
        return rec


def kill_group(proc, grace=10) -> int:
    """SIGTERM the process group of ``proc``, SIGKILL after ``grace``."""
    for sig, wait in ((signal.SIGTERM, grace), (signal.SIGKILL, 5)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            pass
        try:
            return proc.wait(timeout=wait)
        except subprocess.TimeoutExpired:
            continue
    return proc.wait()


def python_env(args, site=None) -> dict:
    """Environment of the steps: the source tree first (cbnet_mmdet,
    cbnet_lab, the peer project), then the installed site, one OpenMP
    thread unless set."""
    env = dict(os.environ)
    paths = [ROOT, osp.join(ROOT, 'projects', 'peer_dehaze')]
    if site:
        paths.append(site)
    if env.get('PYTHONPATH'):
        paths.append(env['PYTHONPATH'])
    env['PYTHONPATH'] = os.pathsep.join(paths)
    env.setdefault('OMP_NUM_THREADS', '1')
    env['PYTHONUNBUFFERED'] = '1'
    env['PIP_DISABLE_PIP_VERSION_CHECK'] = '1'
    if args.pretrained:
        env['CBNET_PRETRAINED_DIR'] = osp.abspath(args.pretrained)
    if args.dry_run:
        # the dry run is a CPU run even where a GPU is
        env['CUDA_VISIBLE_DEVICES'] = ''
    return env


def probe(args, env) -> dict:
    """What the interpreter sees: versions, GPU, mmcv's ops build."""
    code = (
        'import json, os, platform, torch\n'
        'info = dict(python=platform.python_version(), '
        'torch=torch.__version__, cuda=torch.version.cuda, '
        'gpu=torch.cuda.get_device_name(0) if torch.cuda.is_available() '
        'else None, cpu_count=os.cpu_count())\n'
        'if info["gpu"]:\n'
        '    info["capability"] = "%d.%d" % '
        'torch.cuda.get_device_capability(0)\n'
        'try:\n'
        '    import numpy; info["numpy"] = numpy.__version__\n'
        '    import mmcv, mmcv.ops, mmdet, mmengine\n'
        '    from mmcv.ops import get_compiling_cuda_version as v\n'
        '    info.update(mmcv=mmcv.__version__, mmdet=mmdet.__version__, '
        'mmengine=mmengine.__version__, mmcv_ops_cuda=v())\n'
        'except Exception as e:\n'
        '    info["stack_error"] = f"{type(e).__name__}: {e}"\n'
        'print(json.dumps(info))\n')
    out = subprocess.run([args.python, '-c', code], env=env, cwd=ROOT,
                         capture_output=True, text=True, timeout=180)
    try:
        return json.loads(out.stdout.strip().splitlines()[-1])
    except (ValueError, IndexError):
        return dict(probe_error=(out.stderr or out.stdout)[-2000:])


def stack_ok(info) -> bool:
    """torch, mmcv (with ops), mmdet and mmengine import."""
    return 'stack_error' not in info and 'probe_error' not in info


def mmcv_has_cuda(info) -> bool:
    return info.get('mmcv_ops_cuda') not in (None, 'not available')


# --------------------------------------------------------------- set-up ---
def step_setup(r: Runner) -> dict:
    args, t0 = r.args, time.time()
    site = osp.join(r.work, 'site')
    if args.dry_run:
        env = python_env(args)
        info = probe(args, env)
        plan = setup_plan(args)
        note = ('dry run: nothing installed; ' + plan['note'])
        ok = stack_ok(info)
        rec = r.step('setup', 'ok' if ok else 'failed', time.time() - t0,
                     note, probe=info, plan=plan['items'])
        rec['env'] = env
        return rec
    os.makedirs(site, exist_ok=True)
    env = python_env(args, site)
    plan, runs = setup_plan(args), []
    info = probe(args, env)
    if stack_ok(info) and (mmcv_has_cuda(info) or not info.get('gpu')):
        # a second call on a still-warm machine: the first one's install
        r.log(f'the stack in {site} imports (mmcv CUDA ops: '
              f'{info.get("mmcv_ops_cuda")}): kept')
        return dict(r.step('setup', 'ok', time.time() - t0,
                           'kept what an earlier call installed',
                           probe=info), env=env)
    if plan['missing']:
        return dict(r.step('setup', 'failed', time.time() - t0,
                           'missing in --wheels: ' +
                           ', '.join(plan['missing'])), env=env)
    pip = [args.python, '-m', 'pip', 'install', '-q', '--no-index',
           '--no-deps', '--no-compile', '--no-cache-dir', '--upgrade',
           '--target', site]
    if plan['wheels']:
        runs.append(r.run(pip + plan['wheels'],
                          min(BOXES['install'], r.left()), 'setup_install',
                          env))
    if plan['mmcv_wheel']:
        runs.append(r.run(pip + [plan['mmcv_wheel']],
                          min(BOXES['install'], r.left()), 'setup_mmcv',
                          env))
    elif info.get('gpu'):
        built = build_mmcv(r, plan['mmcv_sdist'], env, info, True, runs)
        if built:
            runs.append(r.run(pip + [built], min(BOXES['install'], r.left()),
                              'setup_mmcv', env))
            return_wheel(r, built)
    info = probe(args, env)
    if not stack_ok(info) and plan['mmcv_sdist']:
        r.log('no mmcv with CUDA ops: the fallback, mmcv with CPU ops only')
        built = build_mmcv(r, plan['mmcv_sdist'], env, info, False, runs)
        if built:
            runs.append(r.run(pip + [built], min(BOXES['install'], r.left()),
                              'setup_mmcv_cpu', env))
        info = probe(args, env)
    ok = stack_ok(info)
    note = ('mmcv CUDA ops: ' + str(info.get('mmcv_ops_cuda'))
            if ok else info.get('stack_error', info.get('probe_error', '')))
    rec = r.step('setup', 'ok' if ok else 'failed', time.time() - t0, note,
                 probe=info, runs=runs)
    rec['env'] = env
    return rec


def setup_plan(args) -> dict:
    """What the set-up step installs from ``--wheels``."""
    folder = args.wheels
    files = sorted(glob.glob(osp.join(folder, '*'))) if folder and \
        osp.isdir(folder) else []
    mmcv_wheel = [f for f in files if osp.basename(f).startswith('mmcv-')
                  and f.endswith('.whl')]
    mmcv_sdist = [f for f in files if osp.basename(f).startswith('mmcv-')
                  and f.endswith('.tar.gz')]
    wheels = [f for f in files if f.endswith('.whl') and f not in mmcv_wheel]
    names = {osp.basename(f).split('-')[0].lower() for f in wheels}
    want = {w.split('=')[0].split('>')[0].split('<')[0].lower()
            for w in WHEELS}
    missing = sorted(want - names)
    if not mmcv_wheel and not mmcv_sdist:
        missing.append(f'{MMCV} (sdist or a wheel)')
    items = [osp.basename(f) for f in files]
    note = (f'{len(items)} files in --wheels {folder}' if items else
            f'no --wheels folder ({folder}): nothing to install')
    return dict(wheels=wheels, mmcv_wheel=mmcv_wheel[0] if mmcv_wheel
                else None, mmcv_sdist=mmcv_sdist[0] if mmcv_sdist else None,
                missing=missing, items=items, note=note)


def build_mmcv(r: Runner, sdist, env, info, cuda, runs):
    """Build an mmcv wheel from ``sdist`` into ``<work>/wheelhouse``;
    returns its path (None if the build failed or overran)."""
    house = osp.join(r.work, 'wheelhouse', 'cuda' if cuda else 'cpu')
    shutil.rmtree(house, ignore_errors=True)
    os.makedirs(house)
    env = dict(env, MMCV_WITH_OPS='1', FORCE_CUDA='1' if cuda else '0',
               MAX_JOBS=str(os.cpu_count() or 1))
    if cuda:
        env['TORCH_CUDA_ARCH_LIST'] = info.get('capability', '9.0')
    box = BOXES['build' if cuda else 'fallback_build']
    res = r.run([r.args.python, '-m', 'pip', 'wheel', '-v', '--no-deps',
                 '--no-build-isolation', '--no-index', '-w', house, sdist],
                min(box, r.left()), f'setup_build_{"cuda" if cuda else "cpu"}',
                env)
    res['what'] = f'mmcv build, {"CUDA" if cuda else "CPU"} ops'
    runs.append(res)
    wheels = glob.glob(osp.join(house, 'mmcv-*.whl'))
    return wheels[0] if res['rc'] == 0 and wheels else None


def return_wheel(r: Runner, path):
    """Copy the built mmcv wheel to ``--out`` in parts the device tool
    brings back (at most 3 of 15 MiB); a later call carries it."""
    size = osp.getsize(path)
    if size > 3 * PART_BYTES:
        r.log(f'mmcv wheel {size / 2**20:.0f} MiB: too large to bring back')
        return
    with open(path, 'rb') as f:
        k = 0
        while True:
            chunk = f.read(PART_BYTES)
            if not chunk:
                break
            with open(osp.join(r.args.out, f'mmcv-wheel.part{k:02d}'),
                      'wb') as part:
                part.write(chunk)
            k += 1
    with open(osp.join(r.args.out, 'mmcv-wheel.name'), 'w') as f:
        f.write(osp.basename(path) + '\n')
    r.log(f'mmcv wheel {osp.basename(path)} ({size / 2**20:.1f} MiB) '
          f'returned in {k} part(s)')


# ---------------------------------------------------------------- tests ---
#: A CUDA-only test's decorator (tests/conftest.py marks the second kind).
CUDA_TEST = re.compile(r"^@pytest\.mark\.(cuda\b|skipif\(.*"
                       r"reason='needs CUDA'\))", re.M)


def cuda_test_files():
    """Test files holding CUDA-only tests (marked ``cuda``, or skipped
    with 'needs CUDA', which tests/conftest.py marks ``cuda``)."""
    found = []
    for path in sorted(glob.glob(osp.join(ROOT, 'tests', '**', 'test_*.py'),
                                 recursive=True)):
        with open(path) as f:
            text = f.read()
        if CUDA_TEST.search(text):
            found.append(osp.relpath(path, ROOT))
    return found


def step_tests(r: Runner, env) -> dict:
    t0 = time.time()
    files = cuda_test_files()
    if not files:
        return r.step('tests', 'failed', 0, 'no CUDA test file found')
    junit = osp.join(r.work, 'tests', 'junit.xml')
    os.makedirs(osp.dirname(junit), exist_ok=True)
    res = r.run([r.args.python, '-m', 'pytest', '-q', '-m', 'cuda',
                 '-p', 'no:cacheprovider', f'--junitxml={junit}'] + files,
                min(BOXES['tests'] if not r.args.dry_run else
                    DRY_BOXES['tests'], r.left()), 'tests', env)
    counts = junit_counts(junit)
    ok = res['rc'] == 0 and counts.get('tests', 0) > 0
    return r.step('tests', 'timed out' if res['timed_out'] else
                  'ok' if ok else 'failed', time.time() - t0,
                  ', '.join(f'{k} {v}' for k, v in counts.items()),
                  files=files, counts=counts, runs=[res])


def junit_counts(path) -> dict:
    """tests / failures / errors / skipped of a JUnit XML report."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        return {}
    suite = root if root.tag == 'testsuite' else root.find('testsuite')
    return {k: int(suite.get(k, 0))
            for k in ('tests', 'failures', 'errors', 'skipped')}


# ---------------------------------------------------------------- speed ---
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


# -------------------------------------------------------------- harness ---
def set_spec(name) -> dict:
    if name not in SETS:
        raise SystemExit(f'run_all: unknown harness set {name!r}; known: '
                         f'{sorted(SETS)} (SETS in {__file__})')
    return SETS[name]


def count_runs(args, env, set_name, set_args) -> int:
    """Recipes x seeds of a set (``--only`` honoured)."""
    seeds = option_values(set_args, '--seeds') or ['0', '1', '2']
    only = option_values(set_args, '--only')
    if only:
        return len(only) * len(seeds)
    code = ('import sys; from cbnet_lab.recipe_comparison import '
            'RECIPE_SETS; print(len(RECIPE_SETS[sys.argv[1]]))')
    out = subprocess.run([args.python, '-c', code, set_name], env=env,
                         cwd=ROOT, capture_output=True, text=True,
                         timeout=120)
    try:
        return int(out.stdout.strip()) * len(seeds)
    except ValueError:
        raise RuntimeError(f'cannot count the recipes of {set_name!r}: '
                           f'{out.stderr[-1000:]}')


def option_values(argv, option):
    """The values after ``option`` in ``argv`` (up to the next option)."""
    if option not in argv:
        return []
    vals = []
    for v in argv[argv.index(option) + 1:]:
        if v.startswith('--'):
            break
        vals.append(v)
    return vals


def set_data(r: Runner, env, name, spec, key='data', tiny_key='tiny'):
    """A folder of the set (``key``: its training data, or ``'transfer'``,
    the folder it is also tested on): carried, made on the machine by the
    set's ``make`` command (training data only), or, in a dry run, tiny
    data written here."""
    folder = spec[key]
    path = osp.join(r.args.data, folder) if r.args.data else None
    if path and osp.isdir(path):
        return path, 'carried'
    make = spec.get('make') if key == 'data' else None
    if make and not r.args.dry_run:
        path = osp.join(r.work, 'data', folder)
        if not osp.isdir(path):
            argv = [a.format(path=path, nproc=os.cpu_count() or 1)
                    for a in make]
            res = r.run([r.args.python] + argv, BOXES['make_data'],
                        f'harness_{name}_{key}_make', env)
            if res['rc'] != 0:
                return None, (f'{folder} could not be made: '
                              f'{" ".join(make)} (its log in the records)')
        return path, 'made on the machine'
    if not r.args.dry_run:
        return None, (f'{key} of set {name!r} not found: {path} (carry '
                      'it, docs/benchmarks.md)')
    path = osp.join(r.work, 'data', f'{name}_{key}')
    if not osp.isdir(path):
        if not spec.get(tiny_key):
            return None, (f'set {name!r} has no tiny {key} of its own: '
                          f'give its converted folder under --data')
        module, func = spec[tiny_key].split(':')
        code = (f'import sys; from {module} import {func}; '
                f'{func}(sys.argv[1])')
        res = r.run([r.args.python, '-c', code, path], 120,
                    f'harness_{name}_{key}_tiny', env)
        if res['rc'] != 0:
            return None, f'tiny {key} could not be written'
    return path, 'tiny, generated (dry run)'


def tiny_weights(r: Runner, env, name, writer):
    """A dry run's stand-ins of a set's pretrained files (``writer``:
    ``module:function(folder)``) in a folder of their own: the
    environment that points the configs at it, and how they were had."""
    folder = osp.join(r.work, 'pretrained_tiny', name)
    module, func = writer.split(':')
    code = f'import sys; from {module} import {func}; {func}(sys.argv[1])'
    res = r.run([r.args.python, '-c', code, folder], 120,
                f'harness_{name}_weights_tiny', env)
    if res['rc'] != 0:
        return None, 'stand-in weights could not be written'
    return dict(env, CBNET_PRETRAINED_DIR=folder), \
        'stand-ins, generated (dry run)'


def step_harness(r: Runner, env) -> dict:
    t0, sets = time.time(), []
    dry = r.args.dry_run
    for i, name in enumerate(r.args.sets):
        spec = set_spec(name)
        reserve = (DRY_BOXES if dry else BOXES)['report'] + \
            (DRY_BOXES if dry else BOXES)['pack']
        share = (r.left() - reserve) / (len(r.args.sets) - i)
        rec = dict(set=name)
        sets.append(rec)
        if share < MIN_HARNESS_S['dry' if dry else 'real']:
            rec['status'] = 'skipped'
            rec['note'] = f'{share:.0f} s left for it'
            continue
        data, how = set_data(r, env, name, spec)
        rec['data'] = how
        transfer = None
        if data is not None and spec.get('transfer'):
            transfer, how = set_data(r, env, name, spec, 'transfer',
                                     'transfer_tiny')
            rec['transfer'] = how
        missing = [p for p in spec['dry_needs' if dry else 'needs']
                   if not osp.exists(osp.join(ROOT, p))]
        if data is None or (spec.get('transfer') and transfer is None) \
                or missing:
            rec['status'] = 'failed'
            rec['note'] = how if not missing else \
                f'missing (carry them): {missing}'
            continue
        set_args = list(spec['dry_args' if dry else 'args'])
        work = osp.join(r.work, 'harness', name)
        set_env = env
        if dry and spec.get('tiny_weights') and not r.args.pretrained:
            set_env, how = tiny_weights(r, env, name, spec['tiny_weights'])
            rec['weights'] = how
            if set_env is None:
                rec['status'] = 'failed'
                rec['note'] = how
                continue
        cmd = [r.args.python,
               osp.join('tools', 'analysis_tools', 'compare_recipes.py'),
               '--set', name, '--data-root', data, '--work-dir', work,
               '--threads', '1'] + set_args
        if transfer is not None:
            cmd += ['--transfer-root', transfer]
        source = spec.get('weights_from')
        if source in r.args.sets[:i]:  # ran earlier in this call
            trained = osp.join(r.work, 'harness', source)
            if osp.isdir(trained):
                cmd += ['--weights-from', trained]
        n = min(count_runs(r.args, set_env, name, set_args),
                r.args.max_procs)
        cmd += ['--jobs', str(n)]  # one command, n worker processes
        rec.update(processes=n, command=' '.join(map(shlex.quote, cmd)))
        r.log(f'harness {name}: {n} processes, box {share:.0f} s')
        launched = time.time()
        res = rec['result'] = run_parallel(r, cmd, 1, share,
                                           f'harness_{name}', set_env)
        record = osp.join(work, 'compare.json')
        if res['rc'] != 0 or not osp.isfile(record) or \
                osp.getmtime(record) < launched:
            # cut off (or a process failed): tabulate the finished runs
            rec['report'] = r.run(cmd + ['--report-only'],
                                  (DRY_BOXES if dry else BOXES)['report'],
                                  f'harness_{name}_report', set_env)
        rec.update(harness_record(work))
        done = rec.get('runs_finished', 0)
        complete = res['rc'] == 0 and done and not rec.get('missing')
        rec['status'] = 'ok' if complete else 'partial' if done \
            else 'failed'
    states = {s['status'] for s in sets}
    status = 'ok' if states == {'ok'} else 'skipped' if states == {
        'skipped'} else 'partial' if states & {'ok', 'partial'} else 'failed'
    return r.step('harness', status, time.time() - t0,
                  '; '.join(f"{s['set']}: {s['status']}" for s in sets),
                  sets=sets)


def run_parallel(r: Runner, cmd, n, box, log_name, env) -> dict:
    """``n`` copies of ``cmd`` at once (one process group), ``box``
    seconds at most."""
    log = shlex.quote(osp.join(r.work, 'logs', log_name))
    # each process waited for by pid: the call fails if any of them did
    inner = ''.join(f'{" ".join(map(shlex.quote, cmd))} > {log}_p{k}.log '
                    '2>&1 & pids="$pids $!"; ' for k in range(n)) + \
        'rc=0; for p in $pids; do wait $p || rc=$?; done; exit $rc'
    res = r.run(['bash', '-c', inner], box, log_name, env)
    res['command'] = f'{n} processes at once: ' + ' '.join(
        map(shlex.quote, cmd))
    return res


def harness_record(work) -> dict:
    """The set's compare.json: runs finished, left out, summary."""
    try:
        with open(osp.join(work, 'compare.json')) as f:
            rec = json.load(f)
    except (OSError, ValueError):
        return dict(runs_finished=0)
    return dict(runs_finished=len(rec.get('runs', [])),
                missing=rec.get('missing', []),
                budget=rec.get('budget'), machine=rec.get('machine'),
                summary=rec.get('summary'))


# ----------------------------------------------------------------- pack ---
def pack(r: Runner) -> str:
    """records.tar.gz: every record and log under the work folder, without
    checkpoints, data, the installed site or wheels."""
    path = osp.join(r.args.out, 'records.tar.gz')
    skip_dirs = {'site', 'wheelhouse', 'data', 'out'}
    keep = ('.json', '.md', '.log', '.xml', '.png', '.txt')

    def wanted(info):
        parts = info.name.split('/')
        if len(parts) > 1 and parts[1] in skip_dirs:
            return None
        if info.isfile() and not info.name.endswith(keep):
            return None
        if info.isfile() and info.size > 4 * 2**20:
            return None  # a runaway log: its head is in the step record
        return info

    with tarfile.open(path, 'w:gz') as tar:
        tar.add(r.work, arcname='device', filter=wanted)
    return path


def machine_text() -> str:
    parts = [platform.platform(), f'{os.cpu_count()} CPUs']
    try:
        gpu = subprocess.run(['nvidia-smi', '-L'], capture_output=True,
                             text=True, timeout=30).stdout.strip()
        parts.append(gpu or 'no GPU')
    except (OSError, subprocess.TimeoutExpired):
        parts.append('no nvidia-smi')
    parts.append('load ' + ' / '.join(f'{v:.2f}' for v in os.getloadavg()))
    return ', '.join(parts)


# -------------------------------------------------------------- prepare ---
def prepare(args) -> int:
    """Stage what a call carries (wheels, data) and print the device
    tool's ``run`` call with its size: the carried paths and the working
    tree must stay under 64 MiB together."""
    py = args.python
    os.makedirs(args.wheels, exist_ok=True)
    plat = ['--only-binary=:all:', '--python-version', '3.12',
            '--implementation', 'cp', '--platform', 'manylinux_2_28_x86_64',
            '--platform', 'manylinux_2_17_x86_64', '--platform',
            'manylinux2014_x86_64']
    if not setup_plan(args)['items'] or args.refresh:
        subprocess.run([py, '-m', 'pip', 'download', '-q', '--no-deps',
                        '-d', args.wheels] + plat + WHEELS, check=True)
        # the sdist: its metadata step imports torch (this interpreter's)
        subprocess.run([py, '-m', 'pip', 'download', '-q', '--no-deps',
                        '--no-binary', ':all:', '--no-build-isolation',
                        '-d', args.wheels, MMCV], check=True)
    carry = [osp.relpath(args.wheels, ROOT)]
    for name in args.sets:
        spec = set_spec(name)
        # the training data (unless the machine makes it) and the folder
        # the set is also tested on
        folders = [spec[k] for k in ('data', 'transfer') if spec.get(k)
                   and not (k == 'data' and spec.get('make'))]
        for folder in folders:
            src = osp.join(args.data_src, VAL_ONLY.get(folder, (
                folder,))[0]) if args.data_src else None
            dst = osp.join(args.data, folder)
            if src and not osp.isdir(dst):
                if folder in VAL_ONLY:
                    copy_val_only(args.python, src, dst,
                                  *VAL_ONLY[folder][1:])
                else:  # a link would travel as a link
                    shutil.copytree(src, dst)
            if osp.relpath(dst, ROOT) not in carry:
                carry.append(osp.relpath(dst, ROOT))
        carry += [p for p in spec['needs'] if p not in carry]
    if args.pretrained:
        carry.append(osp.relpath(args.pretrained, ROOT))
    sizes = {p: tree_bytes(osp.join(ROOT, p)) for p in carry}
    tracked = subprocess.run(
        ['git', 'ls-files', '-co', '--exclude-standard', '-z'], cwd=ROOT,
        capture_output=True, check=True).stdout.split(b'\0')
    tree = sum(osp.getsize(osp.join(ROOT, p.decode())) for p in tracked
               if p and osp.isfile(osp.join(ROOT, p.decode())))
    total = tree + sum(sizes.values())
    for p, b in [('(working tree)', tree)] + list(sizes.items()):
        print(f'{b / 2**20:8.1f} MiB  {p}')
    print(f'{total / 2**20:8.1f} MiB  total (the device tool takes 64)')
    cmd = ('bash tools/device/run_all.sh --out "$OUT"'
           + (f' --sets {" ".join(args.sets)}') +
           (f' --pretrained {osp.relpath(args.pretrained, ROOT)}'
            if args.pretrained else ''))
    print(json.dumps(dict(command=cmd, carry=carry, timeout_s=600),
                     indent=1))
    missing = [p for p in carry if not osp.exists(osp.join(ROOT, p))]
    if missing:
        print(f'missing, make them first: {missing}', file=sys.stderr)
    if total > 64 * 2**20 or len(carry) > 8:
        print('too much for one call: run the sets in separate calls '
              '(--sets)', file=sys.stderr)
        return 1
    return 1 if missing else 0


def copy_val_only(python, src, dst, val_fraction, seed):
    """Copy a VOC folder's ``Annotations/`` and the photos of the val
    subset of its seeded split (the dataset's own ``seeded_split``, run by
    the project's interpreter: this script imports nothing of it)."""
    code = ('import glob, os.path as osp, sys; from cbnet_mmdet.datasets.'
            'voc_fog import seeded_split; ids = [osp.basename(p)[:-4] for '
            'p in glob.glob(osp.join(sys.argv[1], "Annotations", "*.xml"))]'
            '; print("\\n".join(seeded_split(ids, "val", float(sys.argv[2]), '
            'int(sys.argv[3]))))')
    val = subprocess.run([python, '-c', code, src, str(val_fraction),
                          str(seed)], capture_output=True, text=True,
                         check=True).stdout.split()
    shutil.copytree(osp.join(src, 'Annotations'),
                    osp.join(dst, 'Annotations'))
    os.makedirs(osp.join(dst, 'JPEGImages'))
    photos = {osp.splitext(f)[0]: f for f in
              os.listdir(osp.join(src, 'JPEGImages'))}
    for i in val:
        shutil.copy2(osp.join(src, 'JPEGImages', photos[i]),
                     osp.join(dst, 'JPEGImages', photos[i]))
    return val


def tree_bytes(path) -> int:
    if osp.isfile(path):
        return osp.getsize(path)
    return sum(osp.getsize(osp.join(d, f)) for d, _, fs in os.walk(path)
               for f in fs)


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
                   help=f'harness sets (default {DEFAULT_SETS}; known: '
                   f'{sorted(SETS)})')
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
    for name in args.sets:
        if name not in SETS:
            p.error(f'--sets: unknown {name!r}; known {sorted(SETS)}')
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
        return prepare(args)
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


def git_commit():
    try:
        return subprocess.run(['git', 'rev-parse', 'HEAD'], cwd=ROOT,
                              capture_output=True, text=True,
                              timeout=10).stdout.strip() or None
    except (OSError, subprocess.TimeoutExpired):
        return None


if __name__ == '__main__':
    sys.exit(main())
