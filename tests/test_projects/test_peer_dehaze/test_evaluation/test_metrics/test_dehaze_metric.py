"""CBNetDehazeMetric: PSNR per beta against numpy."""
import math

import numpy as np
import pytest
import torch

import cbnet_dehaze  # noqa: F401
from cbnet_dehaze.evaluation.metrics import CBNetDehazeMetric
from cbnet_dehaze.evaluation.metrics.dehaze_metric import beta_of, psnr
from cbnet_dehaze.models.losses.ssim_loss import ssim


def sample(beta, pred, hazy, gt):
    return dict(foggy_img_path=f'x/leftImg8bit_foggy/val/c/a_leftImg8bit_'
                f'foggy_beta_{beta}.png', pred_img=pred, hazy_img=hazy,
                gt_img=gt)


def test_psnr_matches_numpy():
    rng = np.random.RandomState(0)
    x, y = rng.rand(3, 8, 9), rng.rand(3, 8, 9)
    ref = 10 * math.log10(1 / np.mean((x - y)**2))
    assert psnr(torch.from_numpy(x), torch.from_numpy(y)) == pytest.approx(
        ref)
    assert psnr(torch.from_numpy(x), torch.from_numpy(x)) == 100.0
    assert beta_of('a_leftImg8bit_foggy_beta_0.005.png') == '0.005'


def test_groups_by_beta():
    torch.manual_seed(0)
    metric = CBNetDehazeMetric()
    gts = [torch.rand(3, 12, 14) for _ in range(3)]
    preds = [g + 0.01 * (i + 1) for i, g in enumerate(gts)]
    hazy = [g * 0.5 + 0.4 for g in gts]
    metric.process(None, [sample('0.02', preds[0], hazy[0], gts[0]),
                          sample('0.02', preds[1], hazy[1], gts[1]),
                          sample('0.01', preds[2], hazy[2], gts[2])])
    res = metric.compute_metrics(metric.results)
    assert res['beta_0.02/num'] == 2 and res['beta_0.01/num'] == 1
    assert res['beta_0.02/psnr'] == pytest.approx(
        (psnr(preds[0], gts[0]) + psnr(preds[1], gts[1])) / 2)
    assert res['beta_0.01/psnr'] == pytest.approx(-20 * math.log10(0.03),
                                                  rel=1e-5)
    assert res['beta_0.01/ssim_hazy'] == pytest.approx(
        ssim(hazy[2][None], gts[2][None]).item())
    assert res['psnr'] == pytest.approx(
        sum(psnr(p, g) for p, g in zip(preds, gts)) / 3)


def test_missing_clear_image_is_an_error():
    metric = CBNetDehazeMetric()
    with pytest.raises(KeyError, match='no clear image'):
        metric.process(None, [dict(foggy_img_path='f.png',
                                   pred_img=torch.zeros(3, 2, 2))])
