"""CBNetRunner, the one place where training loads checkpoints.

Checkpoints that cannot be resumed or loaded are named with the problem;
``--resume`` falls back to the newest intact checkpoint and stays inside a
moved or copied work dir; a run stopped by ``CBNetNonFiniteLossHook``
stays stopped (its diverged checkpoints are never resumed) and its check
resumes with its history; MMEngine's allow-list is in force only while the
runner loads. tools/train.py with a toy model, in-process, and MMDet's own
tools/train.py in a subprocess.
"""
import glob
import os.path as osp
import pickle
import shutil
import subprocess
import sys

import mmdet
import pytest
import torch
from mmengine.registry import RUNNERS

from cbnet_mmdet.engine.runner import CBNetRunner
from cbnet_mmdet.utils.checkpoint.files import (DivergedRunError,
                                                read_checkpoint)
from helper_hooks import toy_config, toy_runner
from tiny_configs import REPO, load_tool, subprocess_env

#: The check of the divergence tests: it starts after 5 iterations, so a
#: blow-up at iterations 3-4 is saved in iter_3/iter_4.pth before a NaN
#: at 5 stops the run.
LATE_CHECK = [dict(type='CBNetNonFiniteLossHook', min_history=5)]


def meta_iter(path):
    return read_checkpoint(str(path))['meta']['iter']


@pytest.fixture
def train(restore_environ):
    """Run tools/train.py in-process; returns the runner's log text."""
    module = load_tool('train.py')

    def run(work_dir, *args, max_iters=2, custom_hooks=(), **model):
        cfg = toy_config(str(work_dir), max_iters=max_iters,
                         custom_hooks=custom_hooks, **model)
        module.main([cfg, '--work-dir', str(work_dir), *args])
        logs = sorted(glob.glob(osp.join(str(work_dir), '*', '*.log')))
        return open(logs[-1]).read()

    return run


@pytest.fixture
def trained(tmp_path, train):
    """A work dir after 2 iterations: iter_1.pth, iter_2.pth."""
    work = tmp_path / 'run'
    train(work)
    assert sorted(p.name for p in work.glob('iter_*.pth')) == [
        'iter_1.pth', 'iter_2.pth'
    ]
    return work


def truncate(path, keep=0.5):
    data = open(path, 'rb').read()
    open(path, 'wb').write(data[:int(len(data) * keep)])


def test_resume_falls_back_to_newest_intact_checkpoint(trained, train):
    truncate(trained / 'iter_2.pth')  # killed while writing it
    log = train(trained, '--resume', max_iters=3)
    assert (f'latest checkpoint unusable: checkpoint {trained}/iter_2.pth '
            'is truncated or damaged') in log
    assert ('falling back to the newest intact checkpoint of the work dir: '
            f'{trained}/iter_1.pth (iteration 1)') in log
    assert meta_iter(trained / 'iter_3.pth') == 3
    assert meta_iter(trained / 'iter_2.pth') == 2  # redone


def test_copied_work_dir_resumes_from_its_own_checkpoint(trained, train,
                                                         tmp_path):
    copy = tmp_path / 'copy'
    shutil.copytree(trained, copy)
    # the original folder moves on: its iter_2.pth is another checkpoint
    shutil.copy(trained / 'iter_1.pth', trained / 'iter_2.pth')
    log = train(copy, '--resume', max_iters=3)
    assert (f'last_checkpoint names {trained}/iter_2.pth, outside the work '
            f'dir (moved or copied?): using {copy}/iter_2.pth') in log
    assert f'Auto resumed from {copy}/iter_2.pth' in log
    assert 'Auto resumed from the latest checkpoint' not in log
    # resumed at iteration 2: only iteration 3 was trained
    assert meta_iter(copy / 'iter_3.pth') == 3


@pytest.mark.parametrize('kind,problem', [
    ('bare', 'cannot be resumed: it is a bare state dict, not a training '
     'checkpoint'),
    ('text', 'is not a PyTorch checkpoint (it starts with'),
    ('truncated', 'is truncated or damaged'),
    ('empty', 'is empty (0 bytes)'),
])
def test_resume_path_names_file_and_problem(trained, train, tmp_path, kind,
                                            problem):
    path = tmp_path / f'{kind}.pth'
    if kind == 'bare':
        torch.save(read_checkpoint(str(trained / 'iter_1.pth'))['state_dict'],
                   path)
    elif kind == 'text':
        path.write_text('epoch = 3\nthis is not a checkpoint\n')
    elif kind == 'truncated':
        shutil.copy(trained / 'iter_2.pth', path)
        truncate(path)
    else:
        path.write_bytes(b'')
    with pytest.raises(ValueError) as err:
        train(trained, '--resume', str(path), max_iters=3)
    msg = str(err.value)
    assert msg.startswith(f'--resume {path}: ')
    assert problem in msg
    assert (f'(newest intact checkpoint of {trained}: {trained}/iter_2.pth)'
            in msg)


def test_load_from_truncated_names_file(trained, train, tmp_path):
    path = tmp_path / 'pretrained.pth'
    shutil.copy(trained / 'iter_1.pth', path)
    truncate(path, 0.9)
    with pytest.raises(ValueError, match=f'checkpoint {path} is truncated'):
        train(tmp_path / 'new', '--cfg-options', f'load_from={path}')


def test_read_checkpoint_keeps_refusing_code(tmp_path):
    from cbnet_mmdet.utils.checkpoint.files import (intact_checkpoints,
                                                    read_checkpoint)

    class Payload:

        def __reduce__(self):
            return print, ('pwned', )

    path = tmp_path / 'evil.pth'
    torch.save(dict(state_dict={}, meta={}, x=Payload()), path)
    with pytest.raises(pickle.UnpicklingError,
                       match=f'checkpoint {path} holds the Python object '
                       'print, which .* weights-only loading '
                       'refuses') as err:
        read_checkpoint(str(path))
    # never torch's advice to load it with weights_only=False
    assert 'weights_only' not in str(err.value)
    assert intact_checkpoints(str(tmp_path)) == []
    torch.save(torch.zeros(2), tmp_path / 'tensor.pth')
    with pytest.raises(ValueError, match='holds a Tensor, not a checkpoint'):
        read_checkpoint(str(tmp_path / 'tensor.pth'))


def test_registered_and_named_by_the_runtime_config():
    from mmengine.config import Config
    from mmdet.registry import RUNNERS as MMDET_RUNNERS
    assert MMDET_RUNNERS.get('CBNetRunner') is CBNetRunner
    # MMEngine's RUNNERS.build (MMDetection's tools/train.py) starts from
    # the root registry: the config names the scope
    assert RUNNERS.get('mmdet.CBNetRunner') is CBNetRunner
    runtime = Config.fromfile(
        osp.join(REPO, 'configs', '_base_', 'default_runtime.py'))
    assert runtime.runner_type == 'mmdet.CBNetRunner'


def test_allow_list_in_force_only_while_the_runner_loads(trained):
    """MMEngine's checkpoint (a HistoryBuffer in its message hub) is read by
    the runner; torch's safe globals are unchanged around it."""
    before = set(map(str, torch.serialization.get_safe_globals()))
    with pytest.raises(pickle.UnpicklingError, match='HistoryBuffer'):
        torch.load(trained / 'iter_2.pth')  # MMEngine's on this torch
    runner = toy_runner(trained, dict(type='CBNetRNGStateHook'),
                        max_iters=2, runner=CBNetRunner)
    runner._resume = True
    runner.load_or_resume()
    assert runner.iter == 2
    assert set(map(str, torch.serialization.get_safe_globals())) == before


def diverge(train, work, loss_scale):
    """Train the toy to a stop by CBNetNonFiniteLossHook; the error."""
    with pytest.raises(FloatingPointError) as err:
        train(work, max_iters=6, custom_hooks=LATE_CHECK,
              loss_scale=loss_scale)
    return str(err.value)


def test_diverged_run_resumes_from_its_last_clean_checkpoint(tmp_path,
                                                             train):
    """The checkpoints written after the weights went bad are
    never resumed; a plain --resume falls back to the clean one, saying
    so, and the fixed run (no blow-up) trains on from there."""
    work = tmp_path / 'run'
    msg = diverge(train, work, {3: 1e4, 4: 1e6, 5: 'nan'})
    assert f'the last clean checkpoint is {work}/iter_1.pth' in msg
    log = train(work, '--resume', max_iters=6)
    assert (f'resume: latest checkpoint unusable: {work}/iter_4.pth was '
            f'written after the weights went bad (the run stopped: '
            f'non-finite loss at iteration 5') in log
    assert ('resume: falling back to the last clean checkpoint of the '
            f'work dir: {work}/iter_1.pth (iteration 1)') in log
    assert f'Auto resumed from {work}/iter_1.pth' in log
    # iterations 2-6 trained again: the diverged files are replaced ...
    assert [meta_iter(work / f'iter_{i}.pth') for i in range(1, 7)] == [
        1, 2, 3, 4, 5, 6]
    for name in ('iter_2.pth', 'iter_4.pth'):
        weights = read_checkpoint(str(work / name))['state_dict']
        assert all(torch.isfinite(w).all() and w.abs().max() < 10
                   for w in weights.values())
    # ... and no longer refused
    log = train(work, '--resume', max_iters=7)
    assert 'unusable' not in log
    assert f'Auto resumed from {work}/iter_6.pth' in log


def test_diverged_run_without_a_clean_checkpoint_refuses(tmp_path, train):
    work = tmp_path / 'run'
    msg = diverge(train, work, {2: 1e4, 3: 'nan'})
    assert 'no checkpoint of the work dir is clean: start again' in msg
    with pytest.raises(DivergedRunError) as err:
        train(work, '--resume', max_iters=6)
    assert str(err.value) == (
        f'cannot resume {work}: the run stopped (non-finite loss at '
        f'iteration 3 (epoch 1, batch 2): loss=nan, loss_toy=nan) and its '
        f'checkpoints {work}/iter_1.pth, {work}/iter_2.pth were written '
        f'after the weights went bad; no checkpoint of it is clean: start '
        f'again without --resume (lower the lr or check the data)')
    # the files are left as they were
    assert meta_iter(work / 'iter_2.pth') == 2


def test_resume_path_of_a_diverged_checkpoint_refused(tmp_path, train):
    work = tmp_path / 'run'
    diverge(train, work, {3: 1e4, 4: 1e6, 5: 'nan'})
    with pytest.raises(ValueError) as err:
        train(work, '--resume', str(work / 'iter_3.pth'), max_iters=6)
    assert str(err.value).startswith(
        f'--resume {work}/iter_3.pth: written after the weights went bad '
        f'(the run stopped: non-finite loss at iteration 5')
    assert str(err.value).endswith(
        f'(newest intact checkpoint of {work}: {work}/iter_1.pth)')


def test_copied_diverged_work_dir_keeps_its_record(tmp_path, train):
    """``cp -r`` gives every file a new time: the record names the
    diverged checkpoints by content, so the copy still falls back to its
    clean one (by size and time, the copy resumed the bad iter_4.pth)."""
    work = tmp_path / 'run'
    diverge(train, work, {3: 1e4, 4: 1e6, 5: 'nan'})
    copy = tmp_path / 'copy'
    shutil.copytree(work, copy, copy_function=shutil.copyfile)  # as cp -r
    assert (copy / 'iter_4.pth').stat().st_mtime_ns != \
        (work / 'iter_4.pth').stat().st_mtime_ns
    log = train(copy, '--resume', max_iters=6)
    assert (f'resume: latest checkpoint unusable: {copy}/iter_4.pth was '
            f'written after the weights went bad') in log
    assert f'Auto resumed from {copy}/iter_1.pth' in log


def test_load_from_a_diverged_checkpoint_refused(tmp_path, train):
    """``load_from`` of a checkpoint the record names is refused with the
    message ``--resume`` gives, in the original work dir and in a copy;
    a clean checkpoint of the same run loads."""
    work = tmp_path / 'run'
    diverge(train, work, {3: 1e4, 4: 1e6, 5: 'nan'})
    copy = tmp_path / 'copy'
    shutil.copytree(work, copy, copy_function=shutil.copyfile)
    for folder in (work, copy):
        bad = folder / 'iter_3.pth'
        with pytest.raises(ValueError) as err:
            train(tmp_path / 'new', '--cfg-options', f'load_from={bad}')
        assert str(err.value) == (
            f'load_from {bad}: written after the weights went bad (the run '
            f'stopped: non-finite loss at iteration 5 (epoch 1, batch 4): '
            f'loss=nan, loss_toy=nan) (newest intact checkpoint of '
            f'{folder}: {folder}/iter_1.pth)')
    log = train(tmp_path / 'new', '--cfg-options',
                f'load_from={work}/iter_1.pth')
    assert f'Load checkpoint from {work}/iter_1.pth' in log


def test_divergence_record_of_the_earlier_format_still_read(tmp_path,
                                                            train):
    """A record written as [size, mtime_ns] per file is still honoured."""
    import json
    work = tmp_path / 'run'
    diverge(train, work, {3: 1e4, 4: 1e6, 5: 'nan'})
    record = work / 'diverged.json'
    content = json.loads(record.read_text())
    assert set(content['unsafe']['iter_3.pth']) == {'size', 'sha256'}
    content['unsafe'] = {
        name: [(work / name).stat().st_size,
               (work / name).stat().st_mtime_ns]
        for name in content['unsafe']}
    record.write_text(json.dumps(content))
    with pytest.raises(ValueError, match='written after the weights went'):
        train(work, '--resume', str(work / 'iter_3.pth'), max_iters=6)


def test_the_check_resumes_with_its_history(tmp_path, train):
    """A blow-up right after a resume is judged against the losses before
    the interruption (without them, the first resumed loss would be the
    check's only reference and the blow-up would pass)."""
    work = tmp_path / 'run'
    check = [dict(type='CBNetNonFiniteLossHook')]
    train(work, max_iters=2, custom_hooks=check)
    # the resumed process's first loss (iteration 3) is 1e4 x too big
    with pytest.raises(FloatingPointError,
                       match=r'loss blew up at iteration 3 .* the median '
                       r'\S+ of the last 2 iterations'):
        train(work, '--resume', max_iters=4, custom_hooks=check,
              loss_scale={1: 1e4})


def test_mmdet_train_py_builds_it_and_keeps_a_diverged_run_stopped(
        tmp_path, train):
    """MMDetection's own tools/train.py (what `mim train mmdet` runs) on a
    config naming CBNetRunner: the same fallback as ours."""
    script = osp.join(osp.dirname(mmdet.__file__), '.mim', 'tools',
                      'train.py')
    assert osp.isfile(script), script
    work = tmp_path / 'run'
    diverge(train, work, {3: 1e4, 4: 1e6, 5: 'nan'})
    cfg = toy_config(str(work), max_iters=3)
    proc = subprocess.run(
        [sys.executable, script, cfg, '--work-dir', str(work), '--resume'],
        cwd=REPO, env=subprocess_env(), capture_output=True, text=True,
        timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = proc.stdout + proc.stderr
    assert ('resume: falling back to the last clean checkpoint of the '
            f'work dir: {work}/iter_1.pth (iteration 1)') in out
    assert f'Auto resumed from {work}/iter_1.pth' in out
    assert meta_iter(work / 'iter_3.pth') == 3
