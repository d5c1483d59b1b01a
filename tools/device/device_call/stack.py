"""The set-up step: the OpenMMLab stack from the carried wheels, mmcv
built for the GPU (or with CPU ops only, the fallback), the built wheel
brought back."""
import glob
import os
import os.path as osp
import shutil
import time

from .runner import BOXES, Runner, mmcv_has_cuda, probe, python_env, stack_ok

#: The device tool brings back files of at most 16 MiB.
PART_BYTES = 15 * 2**20


def step_setup(r: Runner, plan) -> dict:
    """Install the stack (``plan``: :func:`setup_plan`'s); the dry run
    only checks it. Returns the step's record with the steps' ``env``."""
    args, t0 = r.args, time.time()
    site = osp.join(r.work, 'site')
    if args.dry_run:
        env = python_env(args)
        info = probe(args, env)
        note = ('dry run: nothing installed; ' + plan['note'])
        ok = stack_ok(info)
        rec = r.step('setup', 'ok' if ok else 'failed', time.time() - t0,
                     note, probe=info, plan=plan['items'])
        rec['env'] = env
        return rec
    os.makedirs(site, exist_ok=True)
    env = python_env(args, site)
    runs = []
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


def setup_plan(folder, requirements, mmcv) -> dict:
    """What the set-up step installs from the wheels ``folder``, and
    which of ``requirements`` (the wheels) and ``mmcv`` it lacks."""
    files = sorted(glob.glob(osp.join(folder, '*'))) if folder and \
        osp.isdir(folder) else []
    mmcv_wheel = [f for f in files if osp.basename(f).startswith('mmcv-')
                  and f.endswith('.whl')]
    mmcv_sdist = [f for f in files if osp.basename(f).startswith('mmcv-')
                  and f.endswith('.tar.gz')]
    wheels = [f for f in files if f.endswith('.whl') and f not in mmcv_wheel]
    names = {osp.basename(f).split('-')[0].lower() for f in wheels}
    want = {w.split('=')[0].split('>')[0].split('<')[0].lower()
            for w in requirements}
    missing = sorted(want - names)
    if not mmcv_wheel and not mmcv_sdist:
        missing.append(f'{mmcv} (sdist or a wheel)')
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
