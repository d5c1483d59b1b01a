"""Kill a training run mid-epoch, resume it, and end bitwise like an
uninterrupted run (model, optimizer, schedulers, iteration, EMA teacher).

Exact equality on CPU: same seed, ``num_workers=0`` and
``CBNetRNGStateHook`` restoring the random generators (without it the
resumed run flips and samples differently and ends with other weights).
"""
import os.path as osp
import re
import shutil
import subprocess

import pytest
import torch
from mmengine.runner import Runner

import cbnet_mmdet  # noqa: F401  (registers; checkpoint allow-list)
import helper_hooks  # noqa: F401  (CBNetTestCrashHook)
from checkpoint_diff import differences
from tiny_configs import demo_cfg, subprocess_env, train_cmd, write_cfg

#: 2 epochs of 2 iterations; the interrupted run dies before iteration 4
#: (0-based 3), i.e. in the middle of epoch 2, after epoch_1.pth.
KILL_AT = 3


def assert_same_training_state(ckpt_a: str, ckpt_b: str) -> dict:
    a, b = torch.load(ckpt_a), torch.load(ckpt_b)  # weights_only default
    for key in ('state_dict', 'optimizer', 'param_schedulers', 'rng_state'):
        diff = differences(a[key], b[key], key)
        assert not diff, f'{len(diff)} differences, e.g. {diff[:5]}'
    for key in ('epoch', 'iter', 'seed'):
        assert a['meta'][key] == b['meta'][key], key
    return a


def without_rng_state_hook(cfg):
    """The config without ``CBNetRNGStateHook`` (in ``default_hooks`` from
    the base runtime, and in the tests' ``custom_hooks``)."""
    cfg.default_hooks.pop('rng_state', None)
    cfg.custom_hooks = [h for h in cfg.custom_hooks
                        if h['type'] != 'CBNetRNGStateHook']
    return cfg


def training_state_differences(ckpt_a: str, ckpt_b: str) -> list:
    a, b = torch.load(ckpt_a), torch.load(ckpt_b)
    return [d for key in ('state_dict', 'optimizer')
            for d in differences(a[key], b[key], key)]


@pytest.mark.slow  # 4 training processes, 11 iterations (see docstring)
def test_sigkill_mid_epoch_then_resume_is_exact(cityscapes_like_root,
                                                tmp_path):
    """... and, as a negative control, the same resume without
    ``CBNetRNGStateHook`` ends with other weights: the hook is what makes
    the resumed run exact. (Two resumes instead of one since the control:
    327 s measured on 2 cores shared with four other test runs, load ~5;
    the one-resume version was ~25 s on idle cores.)"""
    cfg_path = write_cfg(
        demo_cfg(cityscapes_like_root), str(tmp_path / 'cfg.py'))
    no_rng_path = write_cfg(
        without_rng_state_hook(demo_cfg(cityscapes_like_root)),
        str(tmp_path / 'no_rng_cfg.py'))
    kill_cfg = demo_cfg(cityscapes_like_root, extra_imports=['helper_hooks'])
    kill_cfg.custom_hooks.append(
        dict(type='CBNetTestSigkillHook', at_iter=KILL_AT))
    kill_path = write_cfg(kill_cfg, str(tmp_path / 'kill_cfg.py'))
    full, cut = str(tmp_path / 'full'), str(tmp_path / 'cut')
    cut_no_rng = str(tmp_path / 'cut_no_rng')
    # the uninterrupted and the interrupted run side by side (2 cores)
    procs = [
        subprocess.Popen(
            cmd, env=subprocess_env(), stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, text=True)
        for cmd in (train_cmd(cfg_path, full), train_cmd(kill_path, cut))
    ]
    logs = [p.communicate(timeout=240)[0] for p in procs]
    assert procs[0].returncode == 0, logs[0][-3000:]
    assert procs[1].returncode == -9, logs[1][-3000:]  # SIGKILL
    # every training run starts with the dataset's summary line
    assert re.search(
        r'CBNetCityscapesDataset \S+instancesonly_filtered_gtFine_train\.json'
        r': 3 images, \d+ instances, \d+ crowd regions; dropped annotations: '
        r'none; left out by filter_cfg: 1 images', logs[0]), logs[0][:3000]
    assert osp.isfile(osp.join(cut, 'epoch_1.pth'))
    assert not osp.exists(osp.join(cut, 'epoch_2.pth'))
    shutil.copytree(cut, cut_no_rng)
    # `--resume` without a path: the latest checkpoint of the work dir; with
    # and (negative control) without the RNG state hook, side by side
    procs = [
        subprocess.Popen(
            cmd, env=subprocess_env(), stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, text=True)
        for cmd in (train_cmd(cfg_path, cut, '--resume'),
                    train_cmd(no_rng_path, cut_no_rng, '--resume'))
    ]
    (out, out_no_rng) = [p.communicate(timeout=240)[0] for p in procs]
    assert procs[0].returncode == 0, out[-3000:]
    assert procs[1].returncode == 0, out_no_rng[-3000:]
    assert 'resumed epoch: 1, iter: 2' in out
    assert 'random generators restored' in out
    ckpt = assert_same_training_state(
        osp.join(full, 'epoch_2.pth'), osp.join(cut, 'epoch_2.pth'))
    assert (ckpt['meta']['epoch'], ckpt['meta']['iter']) == (2, 4)
    assert 'resumed epoch: 1, iter: 2' in out_no_rng
    assert 'random generators restored' not in out_no_rng
    assert training_state_differences(
        osp.join(full, 'epoch_2.pth'), osp.join(cut_no_rng, 'epoch_2.pth'))


def _runner(root, work_dir, name, crash=False, resume=False) -> Runner:
    cfg = demo_cfg(root, distill=True)
    if crash:
        cfg.custom_hooks.append(
            dict(type='CBNetTestCrashHook', at_iter=KILL_AT))
    cfg.update(work_dir=str(work_dir), experiment_name=name, resume=resume)
    return Runner.from_cfg(cfg)


@pytest.mark.slow  # ~20 s on 2 cores
def test_cbnet_dd_crash_then_resume_is_exact_with_ema_teacher(
        cityscapes_like_root, tmp_path):
    full = _runner(cityscapes_like_root, tmp_path / 'full', 'dd_full')
    full.train()
    cut = _runner(cityscapes_like_root, tmp_path / 'cut', 'dd_cut',
                  crash=True)
    with pytest.raises(KeyboardInterrupt):
        cut.train()
    assert cut.iter == KILL_AT
    resumed = _runner(cityscapes_like_root, tmp_path / 'cut', 'dd_resumed',
                      resume=True)
    resumed.train()
    ckpt = assert_same_training_state(
        str(tmp_path / 'full' / 'epoch_2.pth'),
        str(tmp_path / 'cut' / 'epoch_2.pth'))
    teacher = {k for k in ckpt['state_dict'] if k.startswith('teacher.')}
    assert teacher
    # the EMA teacher is neither the student nor its initial copy
    key = 'roi_head.mask_head.conv_logits.weight'
    sd = ckpt['state_dict']
    assert not torch.equal(sd['teacher.' + key], sd['student.' + key])
