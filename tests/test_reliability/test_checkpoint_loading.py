"""Checkpoints that cannot be resumed or loaded are named with the problem;
``--resume`` falls back to the newest intact checkpoint and stays inside a
moved or copied work dir (tools/train.py with a toy model, in-process)."""
import glob
import os.path as osp
import pickle
import shutil

import pytest
import torch

from helper_hooks import toy_config
from tiny_configs import load_tool


@pytest.fixture
def train(restore_environ):
    """Run tools/train.py in-process; returns the runner's log text."""
    module = load_tool('train.py')

    def run(work_dir, *args, max_iters=2, **model):
        cfg = toy_config(str(work_dir), max_iters=max_iters, **model)
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
    assert torch.load(trained / 'iter_3.pth')['meta']['iter'] == 3
    assert torch.load(trained / 'iter_2.pth')['meta']['iter'] == 2  # redone


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
    assert torch.load(copy / 'iter_3.pth')['meta']['iter'] == 3


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
        torch.save(torch.load(trained / 'iter_1.pth')['state_dict'], path)
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
