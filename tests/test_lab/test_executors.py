"""Where a comparison's runs run (cbnet_lab/executors.py): the order the
sweep starts them in, a failed run, the same tiny comparison in this
process, in two worker processes (--jobs 2) and as Ray tasks on a local
Ray giving the same record, and a sweep killed mid-run resumed."""
import concurrent.futures as cf
import glob
import json
import os
import os.path as osp
import signal
import subprocess
import sys
import threading
import time

import pytest
import torch
from harness_helpers import fake_run, fake_training
from tool_helpers import TEST_IN_PROCESS, load_tool, tool_file

from cbnet_lab import config_edits as ce
from cbnet_lab import executors, plan
from cbnet_lab import recipe_comparison as rc

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
CRPN = osp.join(ROOT, 'configs', 'demo', 'rpn',
                'crpn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
WEIGHTS_SOURCES = plan.weights_sources


class Threads(executors.Executor):
    """Runs in threads of this process: parallel, and the test's stubs
    apply."""

    def __init__(self, slots):
        self.slots = slots
        self.pool = cf.ThreadPoolExecutor(slots)

    def submit(self, fn, job):
        return self.pool.submit(fn, job)

    def close(self):
        self.pool.shutdown()


def recipes_with_a_variant(tmp_path):
    """A recipe and a test-time variant of it (its weights, other test
    settings), as config files."""
    base = tmp_path / 'base.py'
    base.write_text('x = 1\n')
    variant = tmp_path / 'variant.py'
    variant.write_text('x = 2\n')
    return [('base', str(base)), ('variant', str(variant))]


def test_a_variant_starts_after_its_source_the_rest_at_once(
        tmp_path, monkeypatch):
    """Two slots: both seeds' trained runs start at once; each variant
    starts once the run of its seed has finished, never before."""
    events, lock = [], threading.Lock()

    def fake_run_recipe(name, config, seed, *args, **kwargs):
        with lock:
            events.append(('start', name, seed))
        time.sleep(0.3 if name == 'base' else 0.05)
        with lock:
            events.append(('end', name, seed))
        return fake_run(name, seed, 0.5, 0.4)

    fake_training(tmp_path, monkeypatch, fake_run_recipe)
    # the variant's source as --weights-of gives it
    monkeypatch.setattr(plan, 'weights_sources', WEIGHTS_SOURCES)
    with Threads(2) as pool:
        record = rc.compare(recipes_with_a_variant(tmp_path), [0, 1],
                            ce.Budget(iters=1), str(tmp_path / 'data'),
                            [0.02], str(tmp_path / 'out'),
                            log=lambda *a: None, executor=pool,
                            weights_of=dict(variant='base'))
    assert [(r['recipe'], r['seed']) for r in record['runs']] == [
        ('base', 0), ('variant', 0), ('base', 1), ('variant', 1)]
    assert events[:2] == [('start', 'base', 0), ('start', 'base', 1)]
    for seed in (0, 1):
        assert events.index(('start', 'variant', seed)) > \
            events.index(('end', 'base', seed))


def test_a_failed_run_stops_the_sweep_and_a_rerun_goes_on(
        tmp_path, monkeypatch):
    """A run that fails stops the sweep (no run starts after it, its error
    is raised); the runs that finished stay finished: the same comparison
    again reads them back and runs only the others."""
    ran, failing, logs = [], {('y', 0)}, []

    def fake_run_recipe(name, config, seed, budget, data_root, betas,
                        out_dir, *args, **kwargs):
        ran.append((name, seed))
        if (name, seed) in failing:
            raise RuntimeError('killed')
        result = fake_run(name, seed, 0.5, 0.4)
        path = rc.result_file(out_dir, name, seed)
        os.makedirs(osp.dirname(path))
        with open(path, 'w') as f:
            json.dump(result, f)
        return result

    fake_training(tmp_path, monkeypatch, fake_run_recipe)

    def compare():
        return rc.compare([('x', 'x.py'), ('y', 'y.py')], [0, 1],
                          ce.Budget(iters=1), str(tmp_path / 'data'),
                          [0.02], str(tmp_path / 'out'), log=logs.append)

    with pytest.raises(RuntimeError, match='killed'):
        compare()
    assert ran == [('x', 0), ('y', 0)]
    failing.clear()
    ran.clear()
    record = compare()
    assert ran == [('y', 0), ('x', 1), ('y', 1)]
    assert any('x, seed 0: already done' in line for line in logs)
    assert [(r['recipe'], r['seed']) for r in record['runs']] == [
        ('x', 0), ('y', 0), ('x', 1), ('y', 1)]


def test_executor_options(capsys):
    tool = load_tool('analysis_tools/compare_recipes.py')
    args = tool.parse_args(['--set', 'arch'])
    assert (args.executor, args.jobs) == ('local', None)
    args = tool.parse_args(['--set', 'arch', '--executor', 'ray',
                            '--address', 'auto', '--run-gpus', '0.5'])
    assert (args.address, args.run_gpus) == ('auto', 0.5)
    for argv, said in ((['--no-wait'], '--no-wait was removed: runs are '
                        'no longer locked'),
                       (['--jobs', '0'], '--jobs N: N >= 1'),
                       (['--address', 'auto'], 'for --executor ray'),
                       (['--run-cpus', '2'], 'for --executor ray')):
        with pytest.raises(SystemExit):
            tool.parse_args(['--set', 'arch'] + argv)
        assert said in capsys.readouterr().err
    assert type(executors.make_executor()) is executors.InProcess
    assert type(executors.make_executor('local', 1)) is executors.InProcess
    with executors.make_executor('local', 2) as pool:
        assert isinstance(pool, executors.Processes) and pool.slots == 2
    with pytest.raises(ValueError, match='unknown executor'):
        executors.make_executor('slurm')


@pytest.fixture(scope='module')
def tiny(cityscapes_like_root, tmp_path_factory):
    """The tiny comparison: CBNet's Cascade RPN and a test-time variant of
    it (its weights, 100 proposals kept), seeds 0 and 1, 2 iterations,
    clear val; its command (work dir, executor options) and its record
    run in this process."""
    folder = tmp_path_factory.mktemp('executors')
    variant = folder / 'k100.py'
    variant.write_text(f"_base_ = '{CRPN}'\n"
                       'model = dict(test_cfg=dict(rpn=dict('
                       'max_per_img=100)))\n')

    def argv(work_dir, *options):
        return ['--configs', f'CRPN={CRPN}', f'k100={variant}',
                '--weights-of', 'k100=CRPN', '--data-root',
                cityscapes_like_root, '--seeds', '0', '1', '--iters', '2',
                '--batch-size', '2', '--num-workers', '0',
                '--warmup-iters', '1', '--betas', '--work-dir',
                str(folder / work_dir), *options, '--cfg-options',
                *TEST_IN_PROCESS]

    tool = load_tool('analysis_tools/compare_recipes.py')
    return argv, tool.main(argv('in_process')), folder


def without_times(record):
    """A record's runs and summary, less the train times (measured)."""
    runs = [{k: v for k, v in r.items() if k != 'train_time_s'}
            for r in record['runs']]
    summary = json.loads(json.dumps(record['summary']))
    for entry in summary['summary'].values():
        entry.pop('train time (s)')
    return runs, summary


@pytest.mark.slow
@pytest.mark.parametrize('options', [
    ['--jobs', '2'],
    # a local Ray of 2 CPUs, a CPU each run
    ['--executor', 'ray', '--jobs', '2']], ids=['jobs', 'ray'])
def test_other_executors_give_the_same_record(tiny, options):
    """The runs trained in two worker processes, or as Ray tasks, are the
    ones trained one after another in the test's process: the same
    weights, metrics and summary; each variant tested its source's
    weights."""
    argv, in_process, folder = tiny
    work_dir = options[1]
    record = load_tool('analysis_tools/compare_recipes.py').main(
        argv(work_dir, *options))
    assert without_times(record) == without_times(in_process)
    assert [r['weights_of'] for r in record['runs']
            if r['recipe'] == 'k100'] == ['CRPN', 'CRPN']
    if options[1] == 'ray':
        assert record['machine'].startswith('Ray tasks of 1 CPU, 0 GPU')
    budget = ce.Budget(iters=2, batch_size=2, warmup_iters=1,
                       num_workers=0)
    for seed in (0, 1):
        mine, theirs = (torch.load(rc.checkpoint_file(
            str(folder / d), 'CRPN', seed, budget),
            map_location='cpu')['state_dict']
            for d in (work_dir, 'in_process'))
        assert list(mine) == list(theirs)
        for key, value in mine.items():
            torch.testing.assert_close(value, theirs[key], rtol=0, atol=0)


@pytest.mark.slow
def test_a_killed_sweep_resumes(cityscapes_like_root, tmp_path):
    """A sweep of two worker processes killed (its whole process group,
    SIGKILL) once a run has saved a checkpoint: the same command again,
    here in this process, reads back what finished and resumes each run
    cut short from its last checkpoint; no lock file anywhere."""
    work = tmp_path / 'runs'
    argv = ['--configs', f'CRPN={CRPN}', '--data-root',
            cityscapes_like_root, '--seeds', '0', '1', '--iters', '6',
            '--batch-size', '2', '--num-workers', '0', '--warmup-iters', '1',
            '--betas', '--work-dir', str(work), '--threads', '1',
            '--cfg-options', *TEST_IN_PROCESS]
    env = dict(os.environ, OMP_NUM_THREADS='1', PYTHONPATH=os.pathsep.join(
        [ROOT] + [osp.join(ROOT, 'projects', p)
                  for p in ('peer_dehaze', 'edge_serving')]))
    log = tmp_path / 'sweep.log'
    with open(log, 'w') as out:
        sweep = subprocess.Popen(
            [sys.executable, tool_file('analysis_tools/compare_recipes.py'),
             '--jobs', '2'] + argv, cwd=ROOT, env=env, stdout=out,
            stderr=subprocess.STDOUT, start_new_session=True)
        try:
            deadline = time.time() + 600
            while not glob.glob(str(work / 'CRPN' / 'seed*' /
                                    'last_checkpoint')):
                assert sweep.poll() is None, log.read_text()[-3000:]
                assert time.time() < deadline, 'no checkpoint in 10 min'
                time.sleep(0.2)
        finally:
            os.killpg(sweep.pid, signal.SIGKILL)
            sweep.wait()
    run_dirs = {s: osp.dirname(rc.result_file(str(work), 'CRPN', s))
                for s in (0, 1)}
    finished = {s for s, d in run_dirs.items()
                if osp.isfile(osp.join(d, 'result.json'))}
    cut = {s: rc.resume_iter(d) for s, d in run_dirs.items()
           if s not in finished}
    assert cut and any(cut.values()), (finished, cut)
    record = load_tool('analysis_tools/compare_recipes.py').main(argv)
    runs = {r['seed']: r for r in record['runs']}
    assert sorted(runs) == [0, 1]
    for seed, at in cut.items():
        if at:
            assert runs[seed]['resumed_at_iter'] == at
            assert runs[seed]['train_time_extrapolated'] is True
    for seed in finished:
        assert 'resumed_at_iter' not in runs[seed]
    assert not glob.glob(str(work / '**' / '.lock'), recursive=True)
