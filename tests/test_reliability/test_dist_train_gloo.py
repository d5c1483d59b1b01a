"""Two CPU processes (torch.distributed, gloo) through tools/dist_train.sh:
identical weights on every rank, a checkpoint that loads in one process."""
import os
import os.path as osp
import subprocess
import sys

import pytest
import torch
from mmdet.registry import MODELS
from mmdet.structures import DetDataSample
from mmengine.config import Config
from mmengine.registry import init_default_scope
from mmengine.runner import load_checkpoint

import cbnet_mmdet  # noqa: F401  (registers; checkpoint allow-list)
from checkpoint_diff import differences
from tiny_configs import REPO, demo_cfg, subprocess_env, write_cfg


@pytest.mark.slow  # ~30 s on 2 cores (2 processes, 2 iterations each)
def test_two_process_gloo_run(cityscapes_like_root, tmp_path, free_port):
    cfg = demo_cfg(cityscapes_like_root, max_epochs=1, batch_size=1,
                   extra_imports=['helper_hooks'])
    cfg.custom_hooks.append(dict(type='CBNetTestDumpRankWeightsHook'))
    cfg_path = write_cfg(cfg, str(tmp_path / 'cfg.py'))
    work_dir = str(tmp_path / 'work')
    env = subprocess_env()
    env.update(MASTER_PORT=str(free_port), CUDA_VISIBLE_DEVICES='')
    # dist_train.sh runs `python`: the interpreter running the tests
    env['PATH'] = osp.dirname(sys.executable) + os.pathsep + env['PATH']
    proc = subprocess.run(
        ['bash', osp.join(REPO, 'tools', 'dist_train.sh'), cfg_path, '2',
         '--work-dir', work_dir],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=240)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-4000:]
    assert 'Distributed launcher: pytorch' in out
    assert 'Distributed training: True' in out
    # 3 non-empty images, 1 per process and iteration: 2 iterations/epoch
    ckpt_path = osp.join(work_dir, 'epoch_1.pth')
    ckpt = torch.load(ckpt_path)
    assert (ckpt['meta']['epoch'], ckpt['meta']['iter']) == (1, 2)
    assert len(ckpt['rng_state']) == 2  # one state per rank
    ranks = [
        torch.load(osp.join(work_dir, f'rank{r}_after.pth'))
        for r in range(2)
    ]
    diff = differences(ranks[0], ranks[1])
    assert not diff, f'ranks differ at {diff[:5]}'
    diff = differences(ranks[0], ckpt['state_dict'])
    assert not diff, f'checkpoint differs from rank 0 at {diff[:5]}'
    # they trained: every parameter the loss reaches moved
    init = torch.load(osp.join(work_dir, 'rank0_before.pth'))
    assert len(differences(init, ranks[0])) > 0.9 * len(init)

    # single process: the checkpoint loads strictly and the model predicts
    init_default_scope('mmdet')
    model = MODELS.build(Config.fromfile(cfg_path).model)
    load_checkpoint(model, ckpt_path,
                    map_location='cpu', strict=True)
    model.eval()
    sample = DetDataSample(metainfo=dict(
        img_shape=(64, 128), ori_shape=(64, 128), scale_factor=(1., 1.)))
    data = dict(
        inputs=[torch.randint(0, 255, (3, 64, 128), dtype=torch.uint8)],
        data_samples=[sample])
    with torch.no_grad():
        pred = model.test_step(data)[0].pred_instances
    assert torch.isfinite(pred.bboxes).all()
    assert pred.masks.shape[1:] == (64, 128)
