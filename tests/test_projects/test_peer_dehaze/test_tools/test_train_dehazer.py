"""projects/peer_dehaze/tools/train_dehazer.py on the tiny generated
dataset."""
import glob
import json
import math
import os.path as osp

import cv2
import numpy as np
import pytest
import torch
from mmdet.registry import MODELS
from tool_helpers import load_tool

from cbnet_dehaze.models.dehazers import load_dehazer_checkpoint
from cbnet_mmdet.datasets.cityscapes_paths import foggy_path

ROOT = osp.abspath(osp.join(osp.dirname(__file__), *['..'] * 4))
CONFIGS = osp.join(ROOT, 'projects', 'peer_dehaze', 'configs')
LEARNED = osp.join(CONFIGS, 'dehazer_attention_1xb4-600it_cityscapes-like.py')


@pytest.fixture(scope='module')
def tool():
    return load_tool('projects/peer_dehaze/tools/train_dehazer.py')


def hazy_psnr_from_files(root, beta):
    """Mean PSNR of the foggy val images vs the clear ones, with numpy."""
    values = []
    for clear in sorted(glob.glob(osp.join(root, 'leftImg8bit', 'val', '*',
                                           '*_leftImg8bit.png'))):
        a = cv2.imread(clear).astype(np.float64) / 255
        b = cv2.imread(foggy_path(clear, beta)).astype(np.float64) / 255
        values.append(-10 * math.log10(np.mean((a - b)**2)))
    return float(np.mean(values)), len(values)


def test_trains_evaluates_and_draws(tool, cityscapes_like_root, tmp_path):
    work = tmp_path / 'work'
    metrics = tool.main([
        LEARNED, '--data-root', cityscapes_like_root, '--work-dir',
        str(work), '--max-iters', '2', '--betas', '0.01', '0.02',
        '--cfg-options', 'train_dataloader.batch_size=2',
        'train_dataloader.num_workers=0', 'val_dataloader.num_workers=0',
        'test_dataloader.num_workers=0'
    ])
    for beta in ('0.01', '0.02'):
        ref, n = hazy_psnr_from_files(cityscapes_like_root, float(beta))
        assert metrics[f'dehaze/beta_{beta}/num'] == n == 3
        # the hazy baseline is computed on the files, independently
        assert metrics[f'dehaze/beta_{beta}/psnr_hazy'] == pytest.approx(
            ref, abs=1e-6)
        for key in ('psnr', 'ssim', 'ssim_hazy'):
            assert math.isfinite(metrics[f'dehaze/beta_{beta}/{key}'])
    assert 'dehaze/beta_0.005/num' not in metrics
    saved = json.loads((work / 'dehaze_metrics.json').read_text())
    assert saved == pytest.approx(metrics)
    table = (work / 'dehaze_metrics.md').read_text()
    assert '| 0.01 | 3 |' in table and '| 0.02 | 3 |' in table
    picture = cv2.imread(str(work / 'dehaze_examples.png'))
    assert picture.shape == (2 * 128, 3 * 256, 3)  # 2 betas x 1 example
    # the checkpoint of the training run loads into a bare dehazer
    ckpt = work / 'iter_2.pth'
    assert ckpt.exists()
    dehazer = MODELS.build(dict(type='CBNetAttentionDehazer'))
    report = load_dehazer_checkpoint(dehazer, str(ckpt))
    assert not report['missing'] and not report['mismatched']
    state = torch.load(ckpt, weights_only=True)['state_dict']
    # two Adam steps moved the tail away from its zero init
    assert state['dehazer.tail.weight'].abs().sum() > 0
    torch.testing.assert_close(dehazer.tail.weight,
                               state['dehazer.tail.weight'])


def test_dark_channel_prior_evaluates_without_training(
        tool, cityscapes_like_root, tmp_path):
    work = tmp_path / 'dcp'
    metrics = tool.main([
        osp.join(CONFIGS, 'dehazer_dcp_cityscapes-like.py'), '--data-root',
        cityscapes_like_root, '--work-dir', str(work), '--betas', '0.02',
        '--cfg-options', 'test_dataloader.num_workers=0'
    ])
    assert metrics['dehaze/beta_0.02/num'] == 3
    assert math.isfinite(metrics['dehaze/beta_0.02/psnr'])
    # the dehazed image differs from the hazy input
    assert metrics['dehaze/beta_0.02/psnr'] != pytest.approx(
        metrics['dehaze/beta_0.02/psnr_hazy'])
    assert not glob.glob(str(work / '*.pth'))


def test_bad_beta(tool):
    with pytest.raises(ValueError, match='--betas'):
        tool.main([LEARNED, '--betas', '0.03'])
