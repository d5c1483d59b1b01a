"""The harness step: each set of ``--sets`` with compare_recipes.py, every
run (recipe x seed) in its own process at once; its plan from the set's
file (:mod:`.plans`)."""
import json
import os
import os.path as osp
import shlex
import time

from .plans import load_plans
from .runner import BOXES, DRY_BOXES, ROOT, Runner

#: A harness set given less than this is skipped (seconds).
MIN_HARNESS_S = dict(real=120, dry=30)


def set_data(r: Runner, env, name, spec, key='data', tiny_key='tiny'):
    """A folder of the set's plan (``key``: its training data, or
    ``'transfer'``, the folder it is also tested on): carried, made on the
    machine by the folder's ``make`` command (training data only), or, in a
    dry run, tiny data written here."""
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
    plans = load_plans(r.args, env, r.args.sets)
    for i, name in enumerate(r.args.sets):
        spec = plans[name]
        reserve = (DRY_BOXES if dry else BOXES)['report'] + \
            (DRY_BOXES if dry else BOXES)['pack']
        share = (r.left() - reserve) / (len(r.args.sets) - i)
        rec = dict(set=name)
        sets.append(rec)
        if share < MIN_HARNESS_S['dry' if dry else 'real']:
            rec['status'] = 'skipped'
            rec['note'] = f'{share:.0f} s left for it'
            continue
        if spec.get('error'):  # a malformed set file
            rec['status'], rec['note'] = 'failed', spec['error']
            continue
        data, how = set_data(r, env, name, spec)
        rec['data'] = how
        transfer = None
        if data is not None and spec.get('transfer'):
            transfer, how = set_data(r, env, name, spec, 'transfer',
                                     'transfer_tiny')
            rec['transfer'] = how
        missing = [p for p in spec['needs']
                   if not osp.exists(osp.join(ROOT, p))]
        unready = data is None or bool(spec.get('transfer')) and \
            transfer is None  # ``how`` says why
        if unready or missing:
            rec['status'] = 'failed'
            notes = [how] if unready else []
            if missing:
                notes.append(f'missing (carry them): {missing}')
            rec['note'] = '; '.join(notes)
            continue
        set_args = list(spec['args'])
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
        n = min(spec['runs'], r.args.max_procs)
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
