"""PSNR / SSIM of dehazed foggy images against their clear twins."""
import math
from collections import defaultdict
from typing import Dict, List, Optional, Sequence

import torch
from mmdet.registry import METRICS
from mmengine.evaluator import BaseMetric
from mmengine.logging import MMLogger

from cbnet_dehaze.models.losses.ssim_loss import ssim
from cbnet_mmdet.datasets.cityscapes_paths import split_beta

#: Highest PSNR reported (identical images), dB.
MAX_PSNR = 100.0


def psnr(x: torch.Tensor, y: torch.Tensor) -> float:
    """PSNR in dB of two [0, 1] images of one shape (capped at 100)."""
    mse = torch.mean((x.double() - y.double())**2).item()
    return MAX_PSNR if mse <= 10**(-MAX_PSNR / 10) else -10 * math.log10(mse)


def beta_of(path: str) -> str:
    """``'..._foggy_beta_0.02.png' -> '0.02'``; ``'clear'`` otherwise."""
    return split_beta(path)[1]


@METRICS.register_module()
class CBNetDehazeMetric(BaseMetric):
    """PSNR and SSIM of dehazed images per fog density.

    Expects the predictions of ``CBNetDehazeModel`` (``pred_img``,
    ``hazy_img``, ``gt_img``: RGB [0, 1] ``Tensor[3, h, w]``) and
    ``foggy_img_path`` in the metainfo (add it to ``PackDetInputs``'s
    ``meta_keys``), whose ``_foggy_beta_{beta}.png`` suffix groups the
    images. Reports, per beta and over all images, the mean PSNR (dB,
    data range 1) and SSIM (11x11 Gaussian, sigma 1.5) of the dehazed
    image and, for reference, of the hazy input, against the clear image.

    Keys: ``beta_{b}/psnr``, ``beta_{b}/ssim``, ``beta_{b}/psnr_hazy``,
    ``beta_{b}/ssim_hazy``, ``beta_{b}/num`` and ``psnr``, ``ssim``,
    ``psnr_hazy``, ``ssim_hazy`` (all images).
    """

    default_prefix: Optional[str] = 'dehaze'

    def process(self, data_batch, data_samples: Sequence[dict]) -> None:
        """Score each image; keep only the numbers."""
        for sample in data_samples:
            if 'gt_img' not in sample:
                raise KeyError(
                    f'CBNetDehazeMetric: no clear image for '
                    f"{sample.get('foggy_img_path', sample.get('img_path'))}"
                    '; evaluate on CBNetPairedFoggyDataset with '
                    'CBNetLoadPairedImageFromFile')
            pred, hazy, gt = (sample[k].float().cpu()
                              for k in ('pred_img', 'hazy_img', 'gt_img'))
            self.results.append(
                dict(
                    beta=beta_of(sample.get('foggy_img_path')),
                    psnr=psnr(pred, gt),
                    ssim=ssim(pred[None], gt[None]).item(),
                    psnr_hazy=psnr(hazy, gt),
                    ssim_hazy=ssim(hazy[None], gt[None]).item()))

    def compute_metrics(self, results: List[dict]) -> Dict[str, float]:
        """Means per beta and overall."""
        groups = defaultdict(list)
        for r in results:
            groups[r['beta']].append(r)
        keys = ('psnr', 'ssim', 'psnr_hazy', 'ssim_hazy')
        mean = lambda rs, k: sum(r[k] for r in rs) / len(rs)  # noqa: E731
        metrics = {}
        for beta in sorted(groups):
            for k in keys:
                metrics[f'beta_{beta}/{k}'] = mean(groups[beta], k)
            metrics[f'beta_{beta}/num'] = len(groups[beta])
        if results:
            metrics.update({k: mean(results, k) for k in keys})
        MMLogger.get_current_instance().info(
            'dehazing (dehazed | hazy input vs clear): ' + '; '.join(
                f'beta {b}: PSNR {metrics[f"beta_{b}/psnr"]:.2f} | '
                f'{metrics[f"beta_{b}/psnr_hazy"]:.2f} dB, SSIM '
                f'{metrics[f"beta_{b}/ssim"]:.3f} | '
                f'{metrics[f"beta_{b}/ssim_hazy"]:.3f}' for b in groups))
        return metrics
