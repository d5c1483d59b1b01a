"""Training checkpoints load without ``cbnet_mmdet`` imported.

A runner with our configs' default hooks writes a checkpoint; a process
that imports only what a user's would (``mmdet.apis``) reads it with
torch's default ``weights_only`` loading, and ``DetInferencer(weights=
CKPT)`` alone (config from the checkpoint) predicts with it. ``--resume``
restores the message hub exactly.
"""
import glob
import importlib.util
import os
import os.path as osp
import subprocess
import sys

import numpy as np
import pytest
import torch
from mmengine.config import Config
from mmengine.logging.history_buffer import HistoryBuffer
from mmengine.registry import init_default_scope
from mmengine.runner import Runner

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.engine.hooks.weights_only_checkpoint_hook import (
    TAG, from_weights_only, to_weights_only)

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.dirname(
    osp.abspath(__file__)))))
RUNTIME = osp.join(ROOT, 'configs', '_base_', 'default_runtime.py')
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')


def _toy_module():
    """tests/test_utils/test_checkpoint/test_checkpoint_safe_globals.py (its
    toy model and data), loaded by path: the tests are not a package."""
    spec = importlib.util.spec_from_file_location(
        'cbnet_weights_only_toys',
        osp.join(ROOT, 'tests', 'test_utils', 'test_checkpoint',
                 'test_checkpoint_safe_globals.py'))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_TOYS = _toy_module()


def _runner(work_dir, max_epochs, resume=False):
    """A runner with the default hooks of our configs' runtime."""
    hooks = Config.fromfile(RUNTIME).default_hooks
    hooks.checkpoint.update(save_best=None, max_keep_ckpts=-1)
    init_default_scope('mmdet')
    return Runner(
        model=_TOYS._ToyModel(),
        work_dir=str(work_dir),
        train_dataloader=dict(
            dataset=_TOYS._ToyData(),
            sampler=dict(type='DefaultSampler', shuffle=True),
            batch_size=2,
            collate_fn=dict(type='default_collate')),
        optim_wrapper=dict(optimizer=dict(type='AdamW', lr=0.01)),
        param_scheduler=[dict(type='LinearLR', by_epoch=False, begin=0,
                              end=2)],
        train_cfg=dict(by_epoch=True, max_epochs=max_epochs),
        default_hooks=hooks,
        randomness=dict(seed=0),
        resume=resume,
        default_scope='mmdet',
        experiment_name=f'weights_only_{osp.basename(work_dir)}_{resume}')


@pytest.fixture(scope='module')
def run(tmp_path_factory):
    work_dir = tmp_path_factory.mktemp('weights_only_run')
    runner = _runner(work_dir, max_epochs=2)
    runner.train()
    loss = runner.message_hub.get_scalar('train/loss')
    return work_dir, osp.join(work_dir, 'epoch_2.pth'), loss


def _python(code, cwd=ROOT):
    """Run ``code`` in a fresh interpreter; returns the finished process."""
    env = dict(os.environ, OMP_NUM_THREADS='1')
    return subprocess.run([sys.executable, '-c', code], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def test_checkpoint_needs_no_allow_list(run):
    _, path, _ = run
    registered = torch.serialization.get_safe_globals()
    torch.serialization.clear_safe_globals()
    try:
        found = torch.serialization.get_unsafe_globals_in_checkpoint(path)
    finally:
        torch.serialization.add_safe_globals(registered)
    assert found == []


def test_plain_torch_load_in_a_process_without_cbnet_mmdet(run):
    _, path, _ = run
    proc = _python(
        'import sys, torch\n'
        f'ckpt = torch.load({path!r})\n'
        "assert 'cbnet_mmdet' not in sys.modules\n"
        "print(sorted(ckpt), ckpt['meta']['epoch'])\n")
    assert proc.returncode == 0, proc.stderr
    assert "'message_hub'" in proc.stdout and proc.stdout.endswith(' 2\n')


def test_resume_restores_the_message_hub(run):
    work_dir, _, loss = run
    runner = _runner(work_dir, max_epochs=3, resume=True)
    runner.load_or_resume()
    restored = runner.message_hub.get_scalar('train/loss')
    assert isinstance(restored, HistoryBuffer)
    for a, b in zip(restored.data, loss.data):
        np.testing.assert_array_equal(a, b)
        assert a.dtype == b.dtype
    runner.train()
    assert runner.epoch == 3 and runner.iter == 12


def test_conversion_round_trip_is_exact():
    buf = HistoryBuffer([1.5, 2.25], [1, 2], max_length=7)
    obj = dict(a=[np.float32(0.5), (np.arange(3, dtype=np.int16), 'x')],
               b=buf, c=torch.ones(2), d=np.array(['s']))
    plain = to_weights_only(obj)
    assert plain['b'][TAG] == 'HistoryBuffer'
    assert plain['a'][0][TAG] == 'numpy_scalar'
    back = from_weights_only(plain)
    assert type(back['a'][0]) is np.float32 and back['a'][0] == 0.5
    assert isinstance(back['a'][1], tuple) and back['a'][1][1] == 'x'
    assert back['a'][1][0].dtype == np.int16
    np.testing.assert_array_equal(back['a'][1][0], np.arange(3))
    assert back['b'].max_length == 7 and back['b'].mean() == buf.mean()
    assert back['c'] is obj['c']
    assert back['d'] is obj['d']  # no tensor dtype: left as it is


class _DeviceTensor:
    """A tensor as ``torch.load(map_location='cuda')`` returns it, seen by
    NumPy: ``numpy()`` refuses (torch's own message) until ``cpu()``."""

    def __init__(self, tensor):
        self.tensor = tensor

    def numpy(self):
        raise TypeError("can't convert cuda:0 device type tensor to numpy. "
                        'Use Tensor.cpu() to copy the tensor to host memory '
                        'first.')

    def cpu(self):
        return self.tensor


def _on_device(obj, move):
    """The converted checkpoint with its tensors put where ``move`` says."""
    if isinstance(obj, dict):
        return {k: _on_device(v, move) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(_on_device(v, move) for v in obj)
    return move(obj) if torch.is_tensor(obj) else obj


def test_resume_on_a_gpu_brings_arrays_back_to_the_host():
    """``Runner.resume`` loads with ``map_location`` = the training device;
    on a GPU the message hub's arrays arrived there and NumPy refused them
    (found resuming a harness run on an H100, 2026-11-25)."""
    buf = HistoryBuffer([1.5, 2.25], [1, 2], max_length=7)
    plain = to_weights_only(dict(b=buf, s=np.float64(0.25)))
    back = from_weights_only(_on_device(plain, _DeviceTensor))
    assert back['b'].max_length == 7 and back['b'].mean() == buf.mean()
    assert type(back['s']) is np.float64 and back['s'] == 0.25


@pytest.mark.skipif(not torch.cuda.is_available(), reason='needs CUDA')
def test_resume_on_cuda_for_real(tmp_path):
    buf = HistoryBuffer([1.5, 2.25], [1, 2], max_length=7)
    path = str(tmp_path / 'ckpt.pth')
    torch.save(to_weights_only(dict(b=buf)), path)
    back = from_weights_only(torch.load(path, map_location='cuda'))
    np.testing.assert_array_equal(back['b'].data[0], buf.data[0])


@pytest.mark.slow  # builds the demo model and predicts in a subprocess
def test_det_inferencer_from_checkpoint_alone(run, tmp_path,
                                              cityscapes_like_root):
    """``DetInferencer(weights=CKPT)`` with no config, in a process that
    imports only ``mmdet.apis``: the demo detector's weights in the
    checkpoint the runner wrote, its config embedded as tools/train.py
    embeds it."""
    from mmdet.registry import MODELS
    _, path, _ = run
    ckpt = torch.load(path)
    cfg = Config.fromfile(DEMO)
    torch.manual_seed(0)
    init_default_scope('mmdet')
    model = MODELS.build(cfg.model)
    model.init_weights()
    ckpt['state_dict'] = model.state_dict()
    ckpt['meta']['cfg'] = cfg.pretty_text
    ckpt['message_hub']['runtime_info']['cfg'] = cfg.pretty_text
    demo_ckpt = str(tmp_path / 'demo_epoch_2.pth')
    torch.save(ckpt, demo_ckpt)
    image = sorted(glob.glob(osp.join(cityscapes_like_root, 'leftImg8bit',
                                      'val', '*', '*.png')))[0]
    proc = _python(
        'import sys\n'
        'from mmdet.apis import DetInferencer\n'
        "assert 'cbnet_mmdet' not in sys.modules\n"
        f"inferencer = DetInferencer(weights={demo_ckpt!r}, device='cpu',"
        ' show_progress=False)\n'
        f'result = inferencer({image!r})\n'
        "pred = result['predictions'][0]\n"
        "print('boxes', len(pred['bboxes']), len(pred['scores']))\n")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert 'boxes' in proc.stdout
