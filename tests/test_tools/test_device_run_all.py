"""tools/device/run_all.py: the one-call GPU script. Its dry run (every
step on the CPU, tiny budget) end to end, its time boxes, its set-up plan
and the wheel it brings back; every set file's plan (the script holds no
set table of its own)."""
import ast
import glob
import importlib
import importlib.util
import json
import os
import os.path as osp
import re
import subprocess
import sys
import tarfile
import time

import pytest
from tool_helpers import load_tool

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
SCRIPT = osp.join(ROOT, 'tools', 'device', 'run_all.py')


def load_run_all():
    spec = importlib.util.spec_from_file_location('run_all', SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


ra = load_run_all()
# its steps (run_all.py puts tools/device/ on the path)
harness = importlib.import_module('device_call.harness')
plans = importlib.import_module('device_call.plans')
stack = importlib.import_module('device_call.stack')


#: The script's reader of the set files (the project's interpreter).
READ_FACTS = plans.read_facts


@pytest.fixture(autouse=True)
def plans_in_process(monkeypatch):
    """The set files read in this process (what the script reads in the
    project's interpreter, as JSON: the same, checked below), which saves
    each test an interpreter's start."""
    monkeypatch.setattr(plans, 'read_facts', lambda python, env, names:
                        json.loads(json.dumps(plans.set_facts(names))))


def with_plan(monkeypatch, name, **changes):
    """The harness sees set ``name``'s plan with ``changes``."""
    real = plans.load_plans

    def load(args, env, names):
        found = real(args, env, names)
        found[name] = dict(found[name], **changes)
        return found

    monkeypatch.setattr(harness, 'load_plans', load)


def cuda_tests_in_tree():
    """(file, number of CUDA-only tests), read from the sources: the
    reference the script's test step is checked against."""
    found = {}
    for path in glob.glob(osp.join(ROOT, 'tests', '**', 'test_*.py'),
                          recursive=True):
        with open(path) as f:
            n = len(re.findall(r"reason='needs CUDA'\)\ndef test_",
                               f.read()))
        if n:
            found[osp.relpath(path, ROOT)] = n
    return found


def alive(pid) -> bool:
    """Running (a killed child whose parent died first may stay a zombie
    until someone reaps it: that is not running)."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except FileNotFoundError:
        return False


def runner(tmp_path, *extra):
    args = ra.parse_args(['--work-dir', str(tmp_path / 'work'), '--out',
                          str(tmp_path / 'out'), *extra])
    return ra.Runner(args)


@pytest.mark.slow
def test_dry_run_runs_every_step_on_the_cpu(tmp_path):
    """The dry run, as CI runs it: set-up check, the CUDA tests (skipped
    on the CPU, but selected), the speed passes on the CPU (the AMP
    command lines checked), the realfog set on tiny generated data with
    two seeds in parallel; records in the harness's format, packed."""
    out, work = tmp_path / 'out', tmp_path / 'work'
    env = dict(os.environ, OMP_NUM_THREADS='1')
    env.pop('OUT', None)
    start = time.time()
    proc = subprocess.run(
        [sys.executable, SCRIPT, '--dry-run', '--out', str(out),
         '--work-dir', str(work), '--data', str(tmp_path / 'no_data'),
         '--wheels', str(tmp_path / 'no_wheels'),
         '--speed-models', 'cbnet_mit-b0', '--budget', '900',
         '--sets', 'realfog'],
        cwd=str(tmp_path), env=env, capture_output=True, text=True,
        timeout=600)
    took = time.time() - start
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    with open(out / 'summary.json') as f:
        summary = json.load(f)
    assert summary['dry_run'] is True
    steps = {s['name']: s for s in summary['steps']}
    assert list(steps) == ['setup', 'tests', 'speed', 'harness']
    assert all(s['status'] == 'ok' for s in steps.values()), steps
    assert summary['seconds'] <= took
    # set-up: nothing installed, the stack found, mmcv's ops without CUDA
    assert 'nothing installed' in steps['setup']['note']
    assert steps['setup']['probe']['mmcv_ops_cuda'] == 'not available'
    # tests: exactly the CUDA-only tests of the tree, all skipped here
    want = cuda_tests_in_tree()
    assert sorted(steps['tests']['files']) == sorted(want)
    assert steps['tests']['counts'] == dict(
        tests=sum(want.values()), failures=0, errors=0,
        skipped=sum(want.values()))
    # speed: both passes measured on the CPU, the AMP ones checked
    figures = steps['speed']['figures']
    assert sorted(figures) == ['infer_fp32_cpu', 'train_fp32_cpu']
    assert figures['infer_fp32_cpu']['cbnet_mit-b0']['infer_b1_median_s'] > 0
    assert figures['train_fp32_cpu']['cbnet_mit-b0']['train_median_s'] > 0
    (check,) = [r for r in steps['speed']['runs'] if 'checked' in r]
    assert check['rc'] == 0 and len(check['checked']) == 2
    assert all('--amp' in c and '--device cuda' in c and '--size 64' not in c
               for c in check['checked'])
    # harness: YOLOX-Tiny, seeds 0 and 1, two worker processes at once
    (realfog,) = steps['harness']['sets']
    assert realfog['processes'] == 2 and realfog['runs_finished'] == 2
    assert realfog['missing'] == [] and realfog['status'] == 'ok'
    assert realfog['data'] == 'tiny, generated (dry run)'
    assert '--jobs 2' in realfog['command']
    log = (work / 'logs' / 'harness_realfog_p0.log').read_text()
    started = [line for line in log.splitlines() if ': training' in line]
    # both started at once: neither waited for a first run's time
    assert len(started) == 2 and not any('min left' in s for s in started)
    # records: packed, in the harness's format, no checkpoint
    with tarfile.open(out / 'records.tar.gz') as tar:
        names = tar.getnames()
        record = json.load(tar.extractfile(
            'device/harness/realfog/compare.json'))
    assert not [n for n in names if n.endswith('.pth')]
    assert 'device/speed/infer_fp32_cpu/benchmark.json' in names
    assert 'device/tests/junit.xml' in names
    assert [(r['recipe'], r['seed']) for r in record['runs']] == [
        ('YOLOX-Tiny', 0), ('YOLOX-Tiny', 1)]
    assert record['budget']['iters'] == 2
    assert (out / 'run_all.log').read_text().count('step ') == 4


def test_a_step_over_its_box_is_killed_with_its_children(tmp_path):
    """The time box ends the whole process group (a harness step is many
    processes), quickly, and says so."""
    r = runner(tmp_path)
    pid_file = tmp_path / 'child.pid'
    start = time.time()
    res = r.run(['bash', '-c', f'sleep 60 & echo $! > {pid_file}; wait'],
                1, 'sleeper')
    assert res['timed_out'] and res['rc'] != 0
    assert time.time() - start < 15
    child = int(pid_file.read_text())
    time.sleep(0.2)
    assert not alive(child)
    assert (tmp_path / 'work' / 'logs' / 'sleeper.log').exists()


def test_a_stopped_script_takes_its_running_step_with_it(tmp_path):
    """SIGTERM (a caller's time limit) ends the step's process group too:
    it runs in its own session and would otherwise outlive the call."""
    pid_file = tmp_path / 'child.pid'
    code = (
        'import signal, sys, importlib.util\n'
        f'spec = importlib.util.spec_from_file_location("ra", {SCRIPT!r})\n'
        'ra = importlib.util.module_from_spec(spec)\n'
        'spec.loader.exec_module(ra)\n'
        f'args = ra.parse_args(["--work-dir", {str(tmp_path)!r}, '
        f'"--out", {str(tmp_path / "out")!r}])\n'
        'signal.signal(signal.SIGTERM, ra._stop)\n'
        'try:\n'
        f'    ra.Runner(args).run(["bash", "-c", "sleep 60 & echo $! > '
        f'{pid_file}; wait"], 100, "x")\n'
        'except ra.Stopped:\n'
        '    sys.exit(7)\n')
    proc = subprocess.Popen([sys.executable, '-c', code])
    for _ in range(100):
        if pid_file.exists() and pid_file.read_text().strip():
            break
        time.sleep(0.1)
    proc.send_signal(15)
    assert proc.wait(timeout=30) == 7
    time.sleep(0.2)
    assert not alive(int(pid_file.read_text()))


def test_a_command_within_its_box_keeps_its_exit_status(tmp_path):
    r = runner(tmp_path)
    res = r.run(['bash', '-c', 'echo hi; exit 3'], 30, 'three')
    assert res == dict(res, rc=3, timed_out=False)
    assert (tmp_path / 'work' / 'logs' / 'three.log').read_text() == 'hi\n'


def test_harness_processes_run_at_once_and_a_failure_shows(tmp_path):
    r = runner(tmp_path)
    start = time.time()
    res = harness.run_parallel(r, ['sleep', '1'], 4, 30, 'four', None)
    assert res['rc'] == 0 and time.time() - start < 3.5  # not 4 s
    assert res['command'].startswith('4 processes at once: sleep 1')
    assert len(list((tmp_path / 'work' / 'logs').glob('four_p*.log'))) == 4
    # one process of several failing fails the call (a plain `wait` is 0)
    res = harness.run_parallel(r, ['bash', '-c', 'sleep 0.2; exit 4'],
                               3, 30, 'bad', None)
    assert res['rc'] == 4


def test_setup_plan_names_what_the_wheels_folder_lacks(tmp_path):
    wheels = tmp_path / 'whl'
    wheels.mkdir()
    for name in ('mmengine-0.10.7-py3-none-any.whl',
                 'mmdet-3.3.0-py3-none-any.whl'):
        (wheels / name).write_bytes(b'')
    args = ra.parse_args(['--wheels', str(wheels)])
    plan = ra.setup_plan(args)
    assert 'mmengine' not in plan['missing']
    assert 'pycocotools' in plan['missing']
    assert 'mmcv==2.1.0 (sdist or a wheel)' in plan['missing']
    (wheels / 'mmcv-2.1.0.tar.gz').write_bytes(b'')
    plan = ra.setup_plan(args)
    assert plan['mmcv_sdist'].endswith('mmcv-2.1.0.tar.gz')
    assert plan['mmcv_wheel'] is None
    assert not any('mmcv' in m for m in plan['missing'])
    # a wheel an earlier call built is installed instead of building
    built = 'mmcv-2.1.0-cp312-cp312-linux_x86_64.whl'
    (wheels / built).write_bytes(b'')
    plan = ra.setup_plan(args)
    assert plan['mmcv_wheel'].endswith(built)
    assert not any('mmcv' in osp.basename(w) for w in plan['wheels'])


def test_setup_keeps_a_stack_that_already_imports(tmp_path):
    """A second call on a still-warm machine (here: this environment, no
    GPU) installs and builds nothing, even without the wheels."""
    r = runner(tmp_path, '--wheels', str(tmp_path / 'none'))
    rec = ra.step_setup(r)
    assert rec['status'] == 'ok' and 'kept' in rec['note']
    assert rec['probe']['mmcv'] == '2.1.0' and 'runs' not in rec
    assert not (tmp_path / 'work' / 'wheelhouse').exists()


def test_setup_without_the_stack_or_its_wheels_fails_clearly(tmp_path):
    """An interpreter without the stack (a fresh device machine) and a
    wheels folder that lacks some: the step names them, installs
    nothing."""
    bare = tmp_path / 'bare_python'
    bare.write_text('#!/bin/sh\nexit 1\n')
    bare.chmod(0o755)
    r = runner(tmp_path, '--wheels', str(tmp_path / 'none'), '--python',
               str(bare))
    rec = ra.step_setup(r)
    assert rec['status'] == 'failed'
    assert rec['note'].startswith('missing in --wheels: addict, mmdet, '
                                  'mmengine')
    assert 'mmcv==2.1.0 (sdist or a wheel)' in rec['note']
    assert not os.listdir(tmp_path / 'work' / 'site')


def test_the_built_wheel_comes_back_in_parts_that_join(tmp_path,
                                                       monkeypatch):
    monkeypatch.setattr(stack, 'PART_BYTES', 1000)
    r = runner(tmp_path)
    wheel = tmp_path / 'mmcv-2.1.0-cp312-cp312-linux_x86_64.whl'
    data = os.urandom(2500)
    wheel.write_bytes(data)
    stack.return_wheel(r, str(wheel))
    parts = sorted((tmp_path / 'out').glob('mmcv-wheel.part*'))
    assert [p.name for p in parts] == [
        'mmcv-wheel.part00', 'mmcv-wheel.part01', 'mmcv-wheel.part02']
    assert b''.join(p.read_bytes() for p in parts) == data
    assert (tmp_path / 'out' / 'mmcv-wheel.name').read_text().strip() == \
        wheel.name
    # too large for the device tool's limits: nothing, and the log says so
    big = tmp_path / 'big.whl'
    big.write_bytes(b'x' * 3001)
    stack.return_wheel(r, str(big))
    assert len(list((tmp_path / 'out').glob('mmcv-wheel.part*'))) == 3
    assert 'too large' in (tmp_path / 'out' / 'run_all.log').read_text()


def test_a_set_without_its_data_fails_clearly_and_trains_nothing(tmp_path):
    r = runner(tmp_path, '--data', str(tmp_path / 'nothing'))
    rec = ra.step_harness(r, dict(os.environ))
    (realfog,) = rec['sets']
    assert rec['status'] == 'failed' and realfog['status'] == 'failed'
    assert 'data of set' in realfog['note'] and 'dawn_fog' in \
        realfog['note']
    assert not (tmp_path / 'work' / 'harness').exists()


def test_a_set_left_too_little_time_is_skipped(tmp_path):
    r = runner(tmp_path, '--budget', '100')
    rec = ra.step_harness(r, dict(os.environ))
    assert rec['sets'][0]['status'] == 'skipped'
    assert 's left for it' in rec['sets'][0]['note']


@pytest.mark.parametrize('argv, message', [
    (['--steps', 'setup,bench'], "unknown ['bench']"),
    # an unknown set names the set files
    (['--sets', 'nope'], "unknown 'nope'; the set files "
     "(configs/experiments/): ['ablation', 'arch'"),
])
def test_bad_arguments_are_refused(argv, message, capsys):
    with pytest.raises(SystemExit):
        ra.parse_args(argv)
    assert message in capsys.readouterr().err


def test_every_set_file_yields_a_device_plan():
    """Every set file runs on the device (``--sets`` takes it) and in the
    dry run: its folders are ones the presets file says how to have, its
    arguments are ones compare_recipes.py accepts, the device budget is
    its preset's at seeds 0 1 2 (the runs merge with the CPU's records),
    the dry run trains its one row 2 iterations; the writers and commands
    it names exist."""
    from cbnet_lab import recipe_comparison as rc
    from cbnet_lab.sets import load_device_data, load_sets
    tool = load_tool('analysis_tools/compare_recipes.py')
    sets, data = load_sets(), load_device_data()
    assert plans.set_names() == sorted(sets)
    assert set(ra.DEFAULT_SETS) <= set(sets)
    assert ra.parse_args(['--sets', *sets]).sets == list(sets)
    for dry in (False, True):
        args = ra.parse_args(['--dry-run'] if dry else [])
        found = plans.load_plans(args, None, list(sets))
        for name, spec in found.items():
            device = sets[name].device
            assert 'error' not in spec, (name, spec)
            assert spec['data'] in data, name
            assert spec['weights_from'] == (sets[name].trained_as or
                                            {}).get('set')
            got = tool.parse_args(['--set', name] + spec['args'])
            assert got.preset == device.preset
            if dry:
                rows = got.only or [r.name for r in sets[name].recipes]
                assert got.iters == 2 and got.seeds == device.dry_seeds
                assert spec['needs'] == []
            else:
                preset = rc.PRESETS[device.preset]
                rows = sets[name].recipes
                assert got.seeds == [0, 1, 2], name
                assert (got.iters, got.batch_size, got.warmup_iters,
                        got.img_scale) == (preset.iters, preset.batch_size,
                                           preset.warmup_iters,
                                           preset.img_scale)
                assert spec['needs'] == device.needs
            assert spec['runs'] == len(rows) * len(got.seeds)
            if spec['transfer'] is not None:
                assert spec['transfer_source'] in data
            if spec['make']:
                assert osp.isfile(osp.join(ROOT, spec['make'][0]))
            for writer in (spec['tiny'], spec.get('transfer_tiny'),
                           spec['tiny_weights']):
                if writer is not None:
                    module, func = writer.split(':')
                    assert callable(getattr(importlib.import_module(module),
                                            func)), (name, writer)
    # the sets on YOLOX-Nano's COCO file write its stand-ins in a dry run
    for name in ('realfog_coco', 'realfog_coco_trunk',
                 'coco_street_coco_trunk'):
        assert found[name]['tiny_weights'] == (
            'cbnet_tools.synthetic.yolox_checkpoints:tiny_yolox_nano')


def test_the_project_interpreter_reads_the_set_files_alike():
    """The script reads the set files in the project's interpreter (on a
    fresh machine it has no OpenMMLab stack of its own): what comes back
    is what this process reads; an interpreter that cannot read them
    fails every set with why."""
    names = plans.set_names()
    assert READ_FACTS(sys.executable, dict(os.environ), names) == \
        json.loads(json.dumps(plans.set_facts(names)))
    bad = READ_FACTS('/nonexistent/python', None, ['arch'])
    assert 'the set files could not be read' in bad['arch']['error']


def test_the_script_holds_no_set_table():
    """A set is defined by its file alone: the script's sources name no
    set (but the default one), data folder or writer."""
    from cbnet_lab.sets import load_device_data
    data = load_device_data()
    defined = set(plans.set_names()) | set(data) | {
        f'{n}_val' for n, d in data.items() if d.val_only}
    sources = [SCRIPT] + sorted(glob.glob(
        osp.join(ROOT, 'tools', 'device', 'device_call', '*.py')))
    assert len(sources) > 5
    steps = {'setup', 'tests', 'speed', 'harness'}  # 'speed' is a set too
    for path in sources:
        allowed = steps | (set(ra.DEFAULT_SETS) if path == SCRIPT else set())
        with open(path) as f:
            tree = ast.parse(f.read())
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value,
                                                             str):
                assert node.value not in defined - allowed, (path,
                                                             node.value)
                assert 'cbnet_tools.synthetic' not in node.value, path
            elif isinstance(node, ast.keyword):  # dict(realfog=...)
                assert node.arg not in defined, (path, node.arg)
    for gone in ('SETS', 'VAL_ONLY', 'count_runs', 'set_spec'):
        assert not hasattr(ra, gone) and not hasattr(harness, gone)


GOOD_ROW = ("dict(name='stock', config='baselines/"
            "cascade-mask-rcnn_r18_fpn_1xb2-2k_cityscapes-like.py')")
TEST_ROW = "dict(name='dcp', config='a.py', weights_of='stock')"
ZERO_SHOT_ROW = "dict(name='zs', config='b.py', test_only=True)"


@pytest.mark.parametrize('device, match', [
    ('3', 'device must be dict'),
    ("dict(dry_rows='stock')", r"unknown keys \['dry_rows'\]"),
    ("dict(preset='moon')", "unknown preset 'moon'"),
    ("dict(dry_row='nope')", "dry_row 'nope' is no row of the set"),
    ("dict(dry_row='dcp')", "tests the weights of 'stock'"),
    ('dict(dry_seeds=[])', 'dry_seeds must be distinct seeds'),
    ('dict(dry_seeds=[0, 0])', 'dry_seeds must be distinct seeds'),
    ("dict(dry_seeds=['0'])", 'dry_seeds must be distinct seeds'),
    ("dict(needs='a.pth')", 'needs must be paths relative'),
    ("dict(needs=['/abs/a.pth'])", 'needs must be paths relative'),
    ("dict(tiny_weights='cbnet_tools.synthetic.yolox_checkpoints')",
     "tiny_weights must be a writer 'module:function'"),
])
def test_a_malformed_device_key_is_refused(tmp_path, monkeypatch, device,
                                           match):
    """A set file's ``device`` is checked where the set is read: a clear
    error naming the file and the key; on the device the set fails with
    it and nothing trains."""
    from cbnet_lab import sets
    path = tmp_path / 'my_set.py'
    path.write_text(f'recipes = [{GOOD_ROW}, {TEST_ROW}]\n'
                    f'device = {device}\n')
    with pytest.raises(ValueError, match=match) as err:
        sets.load_set('my_set', str(path))
    assert str(path) in str(err.value)
    monkeypatch.setattr(sets, 'set_files', lambda: {'my_set': str(path)})
    r = runner(tmp_path, '--dry-run')
    r.args.sets = ['my_set']
    rec = harness.step_harness(r, dict(os.environ))
    (mine, ) = rec['sets']
    assert mine['status'] == 'failed' and str(path) in mine['note']
    assert re.search(match, mine['note'])
    assert not (tmp_path / 'work' / 'harness').exists()


def test_a_well_formed_device_key_reads_with_its_defaults(tmp_path):
    from cbnet_lab import sets
    path = tmp_path / 'my_set.py'
    path.write_text(f'recipes = [{ZERO_SHOT_ROW}, {GOOD_ROW}]\n')
    spec = sets.load_set('my_set', str(path)).device
    # the first row that trains, seed 0, the set's own preset
    assert spec == sets.DeviceSpec(preset='demo', dry_row='stock')
    path.write_text(f'recipes = [{GOOD_ROW}]\ndevice = dict(dry_row=None, '
                    "preset='bench', dry_seeds=[1, 2], needs=['w/a.pth'],"
                    " tiny_weights='m.n:f')\n")
    assert sets.load_set('my_set', str(path)).device == sets.DeviceSpec(
        preset='bench', dry_row=None, dry_seeds=[1, 2], needs=['w/a.pth'],
        tiny_weights='m.n:f')


@pytest.mark.parametrize('text, match', [
    ('', 'no device_data'),
    ("device_data = dict(d=dict(dry_img_scale=(1, 1), makes=['x']))",
     r"device_data 'd': unknown keys \['makes'\]"),
    ('device_data = dict(d=dict(dry_img_scale=(1, )))',
     'dry_img_scale must be'),
    ("device_data = dict(d=dict(dry_img_scale=(1, 1), make='x.py'))",
     'make must be'),
    ("device_data = dict(d=dict(dry_img_scale=(1, 1), tiny='m'))",
     "tiny must be a writer"),
    ('device_data = dict(d=dict(dry_img_scale=(1, 1), val_only=(30, 0)))',
     'val_only must be'),
    ('device_data = dict(e=dict(dry_img_scale=(1, 1)))',
     r"preset 'x': its folder 'd' \(data/d\) has no device_data entry"),
])
def test_a_malformed_device_data_is_refused(tmp_path, monkeypatch, text,
                                            match):
    from cbnet_lab import sets
    (tmp_path / '_base_').mkdir()
    (tmp_path / '_base_' / 'presets.py').write_text(
        "presets = dict(x=dict(data_root='data/d', iters=1, batch_size=1, "
        f'warmup_iters=0))\n{text}\n')
    monkeypatch.setattr(sets, 'experiments_dir', lambda: str(tmp_path))
    with pytest.raises(ValueError, match=match):
        sets.load_device_data()


def test_a_transfer_set_without_its_real_fog_fails_clearly(tmp_path):
    """fog_transfer trains on COCO street and is also tested on DAWN: the
    second folder missing is named, and nothing trains."""
    (tmp_path / 'data' / 'coco_street').mkdir(parents=True)
    r = runner(tmp_path, '--data', str(tmp_path / 'data'), '--sets',
               'fog_transfer')
    rec = ra.step_harness(r, dict(os.environ))
    (fog,) = rec['sets']
    assert fog['status'] == 'failed' and fog['data'] == 'carried'
    assert 'transfer of set' in fog['note'] and 'dawn_fog_val' in \
        fog['note']
    assert not (tmp_path / 'work' / 'harness').exists()


def test_a_set_missing_a_file_it_needs_names_it_and_trains_nothing(
        tmp_path, monkeypatch):
    """A checkpoint a set's rows read (``needs``) absent from the tree:
    the set fails naming it, with the data problem too when both."""
    (tmp_path / 'data' / 'coco_street').mkdir(parents=True)
    with_plan(monkeypatch, 'fog_transfer',
              needs=['work_dirs/no_such/iter_1.pth'])
    r = runner(tmp_path, '--data', str(tmp_path / 'data'), '--sets',
               'fog_transfer')
    (fog,) = ra.step_harness(r, dict(os.environ))['sets']
    assert fog['status'] == 'failed'
    assert 'transfer of set' in fog['note']
    assert "missing (carry them): ['work_dirs/no_such/iter_1.pth']" in \
        fog['note']
    (tmp_path / 'data' / 'dawn_fog_val').mkdir(parents=True)
    r = runner(tmp_path / 'again', '--data', str(tmp_path / 'data'),
               '--sets', 'fog_transfer')
    (fog,) = ra.step_harness(r, dict(os.environ))['sets']
    assert fog['status'] == 'failed'
    assert fog['note'] == \
        "missing (carry them): ['work_dirs/no_such/iter_1.pth']"
    assert not (tmp_path / 'again' / 'work' / 'harness').exists()


def finished_sets(monkeypatch):
    """Harness sets that finish at once: each command run in parallel is
    kept (the list returned) and leaves the record of a finished set."""
    seen = []

    def fake_parallel(r, cmd, n, box, log_name, env):
        seen.append(cmd)
        work = cmd[cmd.index('--work-dir') + 1]
        os.makedirs(work)
        with open(osp.join(work, 'compare.json'), 'w') as f:
            json.dump(dict(runs=[{}], missing=[]), f)
        return dict(rc=0)

    monkeypatch.setattr(harness, 'run_parallel', fake_parallel)
    return seen


def test_a_set_made_on_the_machine_is_made_then_tested_on_the_transfer(
        tmp_path, monkeypatch):
    """fog_generated_to_real: its generated scenes are made on the machine
    by the set's ``make`` command (here a stand-in writing a folder), the
    carried real fog is passed as --transfer-root."""
    (tmp_path / 'data' / 'dawn_fog_val').mkdir(parents=True)
    with_plan(monkeypatch, 'fog_generated_to_real', make=[
        '-c', 'import os, sys; os.makedirs(sys.argv[1]); '
        'open(os.path.join(sys.argv[1], "made"), "w").write(sys.argv[2])',
        '{path}', '{nproc}'])
    seen = finished_sets(monkeypatch)
    monkeypatch.setattr(ra.Runner, 'run', lambda self, cmd, *a, **k: dict(
        rc=subprocess.run(cmd).returncode))
    r = runner(tmp_path, '--data', str(tmp_path / 'data'), '--sets',
               'fog_generated_to_real')
    rec = ra.step_harness(r, dict(os.environ))
    (g2r,) = rec['sets']
    made = tmp_path / 'work' / 'data' / 'cityscapes_like_bench'
    assert (made / 'made').read_text() == str(os.cpu_count())
    assert g2r['data'] == 'made on the machine'
    assert g2r['transfer'] == 'carried' and g2r['status'] == 'ok'
    (cmd,) = seen
    assert cmd[cmd.index('--data-root') + 1] == str(made)
    assert cmd[cmd.index('--transfer-root') + 1] == str(
        tmp_path / 'data' / 'dawn_fog_val')


def test_fog_transfer_takes_the_weights_coco_street_trained_before_it(
        tmp_path, monkeypatch):
    """With coco_street first in the same call, fog_transfer gets its work
    dir as --weights-from; run alone, it trains its clear rows itself."""
    for folder in ('coco_street', 'dawn_fog_val'):
        (tmp_path / 'data' / folder).mkdir(parents=True)
    # the learned dehazer's checkpoint its dehazer rows need is not what
    # this checks (a clean clone has none; the next test covers it)
    with_plan(monkeypatch, 'fog_transfer', needs=[])
    seen = finished_sets(monkeypatch)
    r = runner(tmp_path, '--data', str(tmp_path / 'data'), '--sets',
               'coco_street', 'fog_transfer')
    rec = ra.step_harness(r, dict(os.environ))
    assert [s['status'] for s in rec['sets']] == ['ok', 'ok']
    street, transfer = seen
    assert '--weights-from' not in street
    assert transfer[transfer.index('--weights-from') + 1] == \
        street[street.index('--work-dir') + 1]
    seen.clear()
    r = runner(tmp_path / 'alone', '--data', str(tmp_path / 'data'),
               '--sets', 'fog_transfer')
    ra.step_harness(r, dict(os.environ))
    assert '--weights-from' not in seen[0]


def test_a_set_whose_data_cannot_be_made_fails_clearly(tmp_path,
                                                       monkeypatch):
    (tmp_path / 'data' / 'dawn_fog_val').mkdir(parents=True)
    with_plan(monkeypatch, 'fog_generated_to_real',
              make=['-c', 'raise SystemExit(3)'])
    r = runner(tmp_path, '--data', str(tmp_path / 'data'), '--sets',
               'fog_generated_to_real')
    rec = ra.step_harness(r, dict(os.environ))
    (g2r,) = rec['sets']
    assert g2r['status'] == 'failed'
    assert 'could not be made' in g2r['note']


def test_prepare_carries_each_sets_folders_once(tmp_path, capsys):
    """--prepare copies the training data and the transfer folder of each
    set (the real fog once for two sets, its val photos only), never the
    data the machine makes; the val photos it keeps are the ones the
    dataset's seeded split reads as val from the full folder."""
    from mmdet.utils import register_all_modules

    from cbnet_mmdet.datasets import CBNetVOCFogDataset
    from cbnet_tools.synthetic.voc_folder import tiny_fog_folder
    src = tmp_path / 'src'
    (src / 'coco_street').mkdir(parents=True)
    (src / 'coco_street' / 'x.txt').write_text('coco')
    (src / 'cityscapes_like_bench').mkdir()
    ids = tiny_fog_folder(str(src / 'dawn_fog'), num_images=10)
    wheels = tmp_path / 'wheels'
    wheels.mkdir()
    (wheels / 'placeholder.whl').write_bytes(b'')  # nothing downloaded
    data = tmp_path / 'data'
    ra.main(['--prepare', '--wheels', str(wheels), '--data', str(data),
             '--data-src', str(src), '--sets', 'fog_transfer',
             'fog_generated_to_real'])
    out = capsys.readouterr().out
    call = json.loads(out[out.index('{'):])
    carried = [osp.normpath(osp.join(ROOT, p)) for p in call['carry']]
    # and the learned dehazer's checkpoint the transfer set's dehazer rows
    # read (its device key's needs)
    dehazer = osp.join(ROOT, 'work_dirs', 'dehaze',
                       'dehazer_attention_1xb4-200it_cityscapes-like',
                       'iter_200.pth')
    assert carried == [str(wheels), str(data / 'coco_street'),
                       str(data / 'dawn_fog_val'), dehazer]
    assert (data / 'coco_street' / 'x.txt').read_text() == 'coco'
    assert not (data / 'cityscapes_like_bench').exists()
    assert '--sets fog_transfer fog_generated_to_real' in call['command']
    # every XML, the val photos only: 3 of the 10 (val_fraction 0.3)
    val = data / 'dawn_fog_val'
    assert len(list((val / 'Annotations').iterdir())) == len(ids)
    kept = sorted(p.stem for p in (val / 'JPEGImages').iterdir())
    assert len(kept) == 3
    register_all_modules()

    def val_photos(root):
        ds = CBNetVOCFogDataset(data_root=str(root), ann_file='',
                                split='val', pipeline=[], test_mode=True)
        return sorted(osp.basename(d['img_path']).rsplit('.', 1)[0]
                      for d in ds.load_data_list())

    assert kept == val_photos(src / 'dawn_fog') == val_photos(val)


@pytest.mark.slow
def test_dry_run_of_the_generated_to_real_set(tmp_path, monkeypatch):
    """The generated -> real set as the dry run runs it: tiny generated
    scenes and a tiny real-fog folder written here, one row for 2
    iterations, tested on generated clear and foggy val and on the fog
    folder (--transfer-root), with a seeded stand-in trunk's weights."""
    import torch
    from mmdet.models.backbones import MobileNetV2

    from cbnet_tools import pretrained as pt
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'weights'))
    os.makedirs(pt.pretrained_dir())
    torch.manual_seed(1)
    torch.save(dict(state_dict=MobileNetV2().state_dict()),
               pt.pretrained_path('mobilenet_v2'))
    r = runner(tmp_path, '--dry-run', '--data', str(tmp_path / 'none'),
               '--sets', 'fog_generated_to_real')
    rec = ra.step_harness(r, dict(os.environ, OMP_NUM_THREADS='1'))
    (g2r,) = rec['sets']
    assert g2r['status'] == 'ok', g2r
    assert g2r['data'] == g2r['transfer'] == 'tiny, generated (dry run)'
    assert '--transfer-root' in g2r['command']
    with open(tmp_path / 'work' / 'harness' / 'fog_generated_to_real' /
              'compare.json') as f:
        (run,) = json.load(f)['runs']
    assert run['recipe'] == 'Cascade Mask R-CNN, generated clear'
    assert list(run['metrics'])[0] == 'clear'
    assert list(run['metrics'])[-1] == 'real fog'


@pytest.mark.slow
@pytest.mark.parametrize('name, row', [
    ('realfog_coco', 'YOLOX-Nano COCO, fine-tuned'),
    # the two-stage cascade on YOLOX-Nano's COCO trunk
    ('realfog_coco_trunk', 'Cascade R-CNN, COCO trunk'),
])
def test_dry_run_of_a_coco_yolox_set_writes_stand_in_weights(tmp_path,
                                                             name, row):
    """A set on the COCO YOLOX-Nano file as the dry run runs it without
    --pretrained: seeded stand-ins of both converted files in a folder of
    the call's own, the set's dry row for 2 iterations on a tiny fog
    folder; the caller's cache is not touched."""
    from cbnet_tools import pretrained as pt
    r = runner(tmp_path, '--dry-run', '--data', str(tmp_path / 'none'),
               '--sets', name)
    env = dict(os.environ, OMP_NUM_THREADS='1')
    env[pt.PRETRAINED_DIR_ENV] = str(tmp_path / 'users_cache')
    rec = ra.step_harness(r, env)
    (coco,) = rec['sets']
    assert coco['status'] == 'ok', coco
    assert coco['weights'] == 'stand-ins, generated (dry run)'
    stand_ins = tmp_path / 'work' / 'pretrained_tiny' / name
    assert sorted(p.name for p in stand_ins.iterdir()) == sorted(
        [pt.PRETRAINED_FILES['yolox_nano']] + list(pt.DERIVED_FILES))
    assert not (tmp_path / 'users_cache').exists()
    with open(tmp_path / 'work' / 'harness' / name / 'compare.json') as f:
        (run,) = json.load(f)['runs']
    assert run['recipe'] == row
    assert 0.0 <= run['metrics']['real fog']['coco/bbox_mAP'] <= 1.0
