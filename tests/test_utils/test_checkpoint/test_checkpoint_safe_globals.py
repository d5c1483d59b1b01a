"""MMEngine checkpoints load with torch's default ``weights_only=True``
inside :func:`mmengine_safe_globals`, and only there."""
import os
import pickle

import pytest
import torch
from mmengine.logging.history_buffer import HistoryBuffer
from mmengine.model import BaseModel
from mmengine.runner import Runner
from torch import nn
from torch.utils.data import Dataset

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.engine.runner import CBNetRunner
from cbnet_mmdet.utils.checkpoint.safe_globals import (allowed_global_names,
                                                       history_buffer_getattr,
                                                       mmengine_safe_globals)


class _ToyModel(BaseModel):

    def __init__(self):
        super().__init__()
        self.fc = nn.Linear(2, 1)

    def forward(self, inputs, data_samples=None, mode='tensor'):
        out = self.fc(inputs)
        return dict(loss=out.pow(2).mean()) if mode == 'loss' else out


class _ToyData(Dataset):

    def __len__(self):
        return 8

    def __getitem__(self, i):
        return dict(inputs=torch.full((2, ), float(i)))


def _runner(work_dir, max_epochs, resume=False, runner=Runner):
    return runner(
        model=_ToyModel(),
        work_dir=str(work_dir),
        train_dataloader=dict(
            dataset=_ToyData(),
            sampler=dict(type='DefaultSampler', shuffle=True),
            batch_size=2,
            collate_fn=dict(type='default_collate')),
        optim_wrapper=dict(optimizer=dict(type='AdamW', lr=0.01)),
        param_scheduler=[
            dict(type='LinearLR', by_epoch=False, begin=0, end=2),
            dict(type='PolyLR', by_epoch=True, begin=0, end=4,
                 convert_to_iter_based=True)
        ],
        train_cfg=dict(by_epoch=True, max_epochs=max_epochs),
        default_hooks=dict(checkpoint=dict(type='CheckpointHook',
                                           interval=1)),
        custom_hooks=[dict(type='EMAHook')],
        randomness=dict(seed=0),
        resume=resume,
        experiment_name=f'toy_{max_epochs}_{resume}')


@pytest.fixture(scope='module')
def checkpoint(tmp_path_factory):
    work_dir = tmp_path_factory.mktemp('toy_run')
    _runner(work_dir, max_epochs=2).train()
    return work_dir, os.path.join(work_dir, 'epoch_2.pth')


def _non_dtype(names):
    return {n for n in names if not n.startswith('numpy.dtypes.')}


def test_allow_list_is_exactly_what_mmengine_writes(checkpoint):
    _, path = checkpoint
    registered = torch.serialization.get_safe_globals()
    torch.serialization.clear_safe_globals()
    try:  # what the file needs beyond torch's own defaults
        found = set(
            torch.serialization.get_unsafe_globals_in_checkpoint(path))
    finally:
        torch.serialization.add_safe_globals(registered)
    allowed = allowed_global_names()
    assert found <= allowed, f'MMEngine now writes {found - allowed}'
    # nothing allow-listed that MMEngine does not write (dtype classes aside)
    assert _non_dtype(found) == _non_dtype(allowed)


def test_default_torch_load_reads_message_hub_in_the_context(checkpoint):
    _, path = checkpoint
    before = set(map(str, torch.serialization.get_safe_globals()))
    with pytest.raises(pickle.UnpicklingError, match='HistoryBuffer'):
        torch.load(path)  # MMEngine 0.10.7's own, on this torch
    with mmengine_safe_globals():
        ckpt = torch.load(path)  # weights_only=True is torch's default
    assert set(map(str, torch.serialization.get_safe_globals())) == before
    buf = ckpt['message_hub']['log_scalars']['train/loss']
    assert isinstance(buf, HistoryBuffer)
    assert buf.min() <= buf.mean() <= buf.max()
    assert ckpt['meta']['epoch'] == 2


def test_cbnet_runner_resumes_from_checkpoint(checkpoint):
    work_dir, _ = checkpoint
    runner = _runner(work_dir, max_epochs=3, resume=True,
                     runner=CBNetRunner)
    runner.train()
    assert runner.iter == 12  # 2 epochs from the checkpoint + 1 more
    assert runner.epoch == 3


class _GetattrPayload:

    def __init__(self, target, name):
        self.target, self.name = target, name

    def __reduce__(self):
        return getattr, (self.target, self.name)


class _SystemPayload:

    def __reduce__(self):
        return os.system, ('echo pwned', )


@pytest.mark.parametrize('payload', [
    _GetattrPayload(HistoryBuffer, '__init__'),
    _GetattrPayload(HistoryBuffer, '_set_default_statistics'),
    _SystemPayload(),
])
def test_malicious_checkpoints_still_refused(tmp_path, payload):
    path = tmp_path / 'evil.pth'
    torch.save({'state_dict': {}, 'x': payload}, path)
    with mmengine_safe_globals(), pytest.raises(pickle.UnpicklingError):
        torch.load(path)


def test_getattr_stand_in_only_serves_statistics():
    assert history_buffer_getattr(HistoryBuffer, 'mean') is \
        HistoryBuffer.mean
    with pytest.raises(pickle.UnpicklingError, match='HistoryBuffer'):
        history_buffer_getattr(os, 'system')
