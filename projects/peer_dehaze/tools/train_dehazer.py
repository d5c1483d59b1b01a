"""Train a dehazer on foggy/clear pairs, report PSNR/SSIM per beta.

Usage::

    python projects/peer_dehaze/tools/train_dehazer.py CONFIG \
        [--data-root DIR] [--work-dir DIR] [--max-iters N] \
        [--betas 0.005 0.01 0.02] \
        [--checkpoint CKPT] [--num-vis 1] [--cfg-options KEY=VALUE ...]

``CONFIG`` is a ``CBNetDehazeModel`` config
(``projects/peer_dehaze/configs/dehazer_*``).
The dehazer is trained with MMEngine's runner (log every ``logger``
interval, checkpoint at the end; dehazers without parameters such as the
dark channel prior, or ``--max-iters 0``, skip training), then tested on
the foggy val split of every beta against the clear images. Writes to the
work dir ``dehaze_metrics.json``, ``dehaze_metrics.md`` (a table: PSNR and
SSIM of the hazy input and of the dehazed image, per beta) and
``dehaze_examples.png`` (rows: hazy | dehazed | clear, one per beta and
example image). Any dataset in the Cityscapes layout with
``leftImg8bit_foggy`` and converted annotations works (``--data-root``).
"""
import argparse
import json
import os
import os.path as osp

import cv2
import numpy as np
import torch
from mmengine.config import Config, DictAction
from mmengine.runner import Runner

import cbnet_dehaze  # noqa: F401  (registers the components)
from cbnet_mmdet.datasets.cityscapes_paths import FOGGY_BETAS
from cbnet_mmdet.utils.markdown import markdown_table


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('config')
    parser.add_argument('--data-root', help='dataset root (Cityscapes '
                        'layout with leftImg8bit_foggy and annotations/)')
    parser.add_argument('--work-dir', help='defaults to '
                        'work_dirs/dehaze/CONFIG_NAME')
    parser.add_argument('--max-iters', type=int,
                        help='training iterations (0: evaluate only)')
    parser.add_argument('--betas', type=float, nargs='+',
                        help='betas to train and evaluate on (default: the '
                        "config's)")
    parser.add_argument('--checkpoint', help='start from these weights '
                        '(MMEngine load_from)')
    parser.add_argument('--num-vis', type=int, default=1,
                        help='example images per beta in the picture')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--cfg-options', nargs='+', action=DictAction,
                        help='override config keys')
    return parser.parse_args(argv)


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


def build_cfg(args) -> Config:
    """The config with the command line's overrides applied."""
    cfg = Config.fromfile(args.config)
    if args.cfg_options:
        cfg.merge_from_dict(args.cfg_options)
    loaders = ('train_dataloader', 'val_dataloader', 'test_dataloader')
    if args.data_root:
        root = osp.join(args.data_root, '')
        for name in loaders:
            set_key(cfg[name], 'data_root', root)
    if args.betas:
        for beta in args.betas:
            if beta not in FOGGY_BETAS:
                raise ValueError(f'--betas: {beta} is not one of '
                                 f'{FOGGY_BETAS}')
        for name in loaders:
            set_betas(cfg[name], args.betas)
    if args.max_iters is not None:
        cfg.train_cfg.max_iters = args.max_iters
        cfg.train_cfg.val_interval = max(args.max_iters, 1)
        for sched in cfg.get('param_scheduler') or []:
            if sched.get('end', 0) > args.max_iters:
                sched['end'] = max(args.max_iters, 1)
            if 'T_max' in sched:
                sched['T_max'] = max(args.max_iters, 1)
        cfg.default_hooks.checkpoint.interval = max(args.max_iters, 1)
    cfg.work_dir = args.work_dir or osp.join(
        'work_dirs', 'dehaze',
        osp.splitext(osp.basename(args.config))[0])
    cfg.load_from = args.checkpoint
    cfg.randomness = dict(seed=args.seed)
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


def main(argv=None) -> dict:
    args = parse_args(argv)
    cfg = build_cfg(args)
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
                      args.num_vis,
                      osp.join(cfg.work_dir, 'dehaze_examples.png'))
    runner.logger.info(f'{n} example rows in '
                       f"{osp.join(cfg.work_dir, 'dehaze_examples.png')}")
    return metrics


if __name__ == '__main__':
    main()
