"""The time-boxed runner of ``tools/device/run_all.py``: each command in
its own process group under its own box, the record of each step, the
steps' environment, what the interpreter sees, the packed records."""
import json
import os
import os.path as osp
import platform
import shlex
import signal
import subprocess
import tarfile
import time

#: The repository.
ROOT = osp.dirname(osp.dirname(osp.dirname(osp.dirname(
    osp.abspath(__file__)))))

#: Time boxes (seconds) of the real run; the harness gets what is left.
BOXES = dict(install=90, build=420, fallback_build=180, tests=90,
             speed_pass=60, report=60, pack=30, make_data=120)
DRY_BOXES = dict(install=30, build=0, fallback_build=0, tests=120,
                 speed_pass=300, report=60, pack=10)


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


def git_commit():
    try:
        return subprocess.run(['git', 'rev-parse', 'HEAD'], cwd=ROOT,
                              capture_output=True, text=True,
                              timeout=10).stdout.strip() or None
    except (OSError, subprocess.TimeoutExpired):
        return None
