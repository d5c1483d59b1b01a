"""Train a dehazer on foggy/clear pairs and report PSNR/SSIM per beta: the
library of ``projects/peer_dehaze/tools/train_dehazer.py``.

:func:`build_cfg` applies the command line's overrides (data root, betas,
iterations, work dir) to a ``CBNetDehazeModel`` config;
:func:`train_and_evaluate` trains it with MMEngine's runner (skipped for a
dehazer without parameters, or ``max_iters`` 0), tests it on the foggy val
split of every beta against the clear images and writes
``dehaze_metrics.{json,md}`` and ``dehaze_examples.png`` to the work dir.
"""
import json
import os
import os.path as osp
from typing import Optional, Sequence

import cv2
import numpy as np
import torch
from mmengine.config import Config
from mmengine.runner import Runner

from cbnet_mmdet.datasets.cityscapes_paths import FOGGY_BETAS
from cbnet_tools.markdown import markdown_table


def set_key(node, key, value):
    """Set ``key`` to ``value`` in every dict of a nested config."""
    if isinstance(node, dict):
        if key in node:
            node[key] = value
        for child in node.values():
            set_key(child, key, value)
    elif isinstance(node, (list, tuple)):
        for child in node:
            set_key(child, key, value)


def set_betas(loader_cfg, betas):
    """Make a ``ConcatDataset`` of one paired dataset per beta."""
    dataset = loader_cfg['dataset']
    template = dataset['datasets'][0] if dataset.get(
        'type') == 'ConcatDataset' else dataset
    loader_cfg['dataset'] = dict(
        type='ConcatDataset',
        datasets=[dict(template, beta=beta) for beta in betas])


def build_cfg(config: str,
              data_root: Optional[str] = None,
              work_dir: Optional[str] = None,
              max_iters: Optional[int] = None,
              betas: Optional[Sequence[float]] = None,
              checkpoint: Optional[str] = None,
              seed: int = 0,
              cfg_options: Optional[dict] = None) -> Config:
    """The config with the command line's overrides applied.

    Args:
        config (str): A ``CBNetDehazeModel`` config file.
        data_root (str, optional): Dataset root for every dataloader.
        work_dir (str, optional): Defaults to
            ``work_dirs/dehaze/CONFIG_NAME``.
        max_iters (int, optional): Training iterations (0: evaluate only);
            the schedule and checkpoint interval follow.
        betas (Sequence[float], optional): Fog densities to train and
            evaluate on (Foggy Cityscapes' three).
        checkpoint (str, optional): Weights to start from (``load_from``).
        seed (int): The runner's seed.
        cfg_options (dict, optional): Config keys to override first.

    Raises:
        ValueError: a beta that Foggy Cityscapes does not have.
    """
    cfg = Config.fromfile(config)
    if cfg_options:
        cfg.merge_from_dict(cfg_options)
    loaders = ('train_dataloader', 'val_dataloader', 'test_dataloader')
    if data_root:
        root = osp.join(data_root, '')
        for name in loaders:
            set_key(cfg[name], 'data_root', root)
    if betas:
        for beta in betas:
            if beta not in FOGGY_BETAS:
                raise ValueError(f'--betas: {beta} is not one of '
                                 f'{FOGGY_BETAS}')
        for name in loaders:
            set_betas(cfg[name], betas)
    if max_iters is not None:
        cfg.train_cfg.max_iters = max_iters
        cfg.train_cfg.val_interval = max(max_iters, 1)
        for sched in cfg.get('param_scheduler') or []:
            if sched.get('end', 0) > max_iters:
                sched['end'] = max(max_iters, 1)
            if 'T_max' in sched:
                sched['T_max'] = max(max_iters, 1)
        cfg.default_hooks.checkpoint.interval = max(max_iters, 1)
    cfg.work_dir = work_dir or osp.join(
        'work_dirs', 'dehaze',
        osp.splitext(osp.basename(config))[0])
    cfg.load_from = checkpoint
    cfg.randomness = dict(seed=seed)
    return cfg


def to_bgr_uint8(img: torch.Tensor) -> np.ndarray:
    """RGB [0, 1] Tensor[3, H, W] -> BGR uint8 [H, W, 3]."""
    arr = img.detach().float().clamp(0, 1).mul(255).round().byte()
    return np.ascontiguousarray(arr.permute(1, 2, 0).flip(-1).cpu().numpy())


def draw_examples(model, dataset, num_per_beta: int, out: str) -> int:
    """Save rows hazy | dehazed | clear; returns the number of rows.

    Args:
        model (CBNetDehazeModel): the (trained) model.
        dataset (ConcatDataset | Dataset): paired val data.
        num_per_beta (int): examples per beta.
        out (str): PNG path.
    """
    parts = getattr(dataset, 'datasets', [dataset])
    rows = []
    model.eval()
    with torch.no_grad():
        for part in parts:
            for idx in range(min(num_per_beta, len(part))):
                batch = model.data_preprocessor(
                    dict(inputs=[part[idx]['inputs']],
                         data_samples=[part[idx]['data_samples']]))
                sample = model(**batch, mode='predict')[0]
                panels = [to_bgr_uint8(sample.get(k)) for k in
                          ('hazy_img', 'pred_img', 'gt_img')]
                row = np.ascontiguousarray(np.concatenate(panels, axis=1))
                cv2.putText(row, f'beta {part.beta}: hazy | dehazed | clear',
                            (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                            (0, 0, 255), 1)
                rows.append(row)
    if rows:
        width = max(r.shape[1] for r in rows)
        rows = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)))
                for r in rows]
        cv2.imwrite(out, np.concatenate(rows, axis=0))
    return len(rows)


def to_markdown(metrics: dict) -> str:
    """Table: beta | PSNR hazy | PSNR dehazed | SSIM hazy | SSIM dehazed."""
    betas = sorted({k.split('/')[1][len('beta_'):] for k in metrics
                    if k.startswith('dehaze/beta_')}, key=float)
    rows = []
    for b in betas:
        g = lambda k: metrics[f'dehaze/beta_{b}/{k}']  # noqa: E731
        rows.append([b, int(g('num')), f'{g("psnr_hazy"):.2f}',
                     f'{g("psnr"):.2f}', f'{g("ssim_hazy"):.3f}',
                     f'{g("ssim"):.3f}'])
    return '\n'.join(markdown_table(
        ['beta', 'images', 'PSNR hazy (dB)', 'PSNR dehazed (dB)',
         'SSIM hazy', 'SSIM dehazed'], rows))


def train_and_evaluate(cfg: Config, num_vis: int = 1) -> dict:
    """Train (when there is something to train), test, write the reports.

    Args:
        cfg (Config): From :func:`build_cfg`.
        num_vis (int): Example images per beta in ``dehaze_examples.png``.

    Returns:
        dict: The test metrics (``dehaze/beta_{b}/psnr`` ...), as floats.
    """
    os.makedirs(cfg.work_dir, exist_ok=True)
    runner = Runner.from_cfg(cfg)
    trainable = any(p.requires_grad for p in runner.model.parameters())
    if trainable and cfg.train_cfg.max_iters > 0:
        runner.train()
    else:
        runner.logger.info('no training (no trainable parameters or '
                           'max_iters 0): evaluating only')
    metrics = runner.test()
    metrics = {k: float(v) for k, v in metrics.items()}
    md = to_markdown(metrics)
    print(md)
    with open(osp.join(cfg.work_dir, 'dehaze_metrics.json'), 'w') as f:
        json.dump(metrics, f, indent=1)
    with open(osp.join(cfg.work_dir, 'dehaze_metrics.md'), 'w') as f:
        f.write(md + '\n')
    n = draw_examples(runner.model, runner.test_dataloader.dataset,
                      num_vis,
                      osp.join(cfg.work_dir, 'dehaze_examples.png'))
    runner.logger.info(f'{n} example rows in '
                       f"{osp.join(cfg.work_dir, 'dehaze_examples.png')}")
    return metrics
