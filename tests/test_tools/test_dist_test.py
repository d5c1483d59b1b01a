"""Smoke test of tools/dist_test.sh: two CPU processes (gloo) evaluate the
demo model (random weights) on the 3 tiny val images; the results of both
ranks are gathered into one file, one per image."""
import os
import os.path as osp
import pickle
import subprocess
import sys

import pytest
from mmengine.config import Config

from tool_helpers import DEMO, REPO, demo_checkpoint


def val_cfg(root: str) -> Config:
    """The demo config evaluating the fixture's val split, in-process."""
    cfg = Config.fromfile(DEMO)
    root = root + '/'
    ann = root + 'annotations/instancesonly_filtered_gtFine_val.json'
    cfg.test_dataloader.update(num_workers=0, persistent_workers=False)
    cfg.test_dataloader.dataset.data_root = root
    for metric in cfg.test_evaluator:
        metric.ann_file = ann
    cfg.log_level = 'INFO'
    return cfg


@pytest.mark.slow  # ~40 s on 2 shared cores (2 processes, 3 images)
def test_two_processes_gather_every_image(cityscapes_like_root, tmp_path,
                                          free_port):
    cfg_path = str(tmp_path / 'cfg.py')
    val_cfg(cityscapes_like_root).dump(cfg_path)
    ckpt = demo_checkpoint(str(tmp_path / 'demo.pth'))
    env = dict(os.environ, MASTER_PORT=str(free_port), OMP_NUM_THREADS='1',
               CUDA_VISIBLE_DEVICES='', PYTHONWARNINGS='ignore')
    # dist_test.sh runs `python`: the interpreter running the tests
    env['PATH'] = osp.dirname(sys.executable) + os.pathsep + env['PATH']
    results = str(tmp_path / 'results.pkl')
    proc = subprocess.run(
        ['bash', osp.join(REPO, 'tools', 'dist_test.sh'), cfg_path, ckpt,
         '2', '--work-dir', str(tmp_path / 'work'), '--out', results],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-4000:]
    assert 'Distributed launcher: pytorch' in out
    assert 'GPU number: 2' in out  # MMEngine's name for the world size
    assert 'coco/segm_mAP' in out and 'cityscapes/mIoU' in out
    with open(results, 'rb') as f:
        dumped = pickle.load(f)
    # 3 images on 2 ranks: the sampler pads to 4, the gather drops the pad
    assert len(dumped) == 3 and len({r['img_id'] for r in dumped}) == 3
