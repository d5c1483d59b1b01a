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

from mmengine.config import DictAction

from cbnet_dehaze.training import build_cfg, train_and_evaluate


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


def main(argv=None) -> dict:
    args = parse_args(argv)
    cfg = build_cfg(args.config, data_root=args.data_root,
                    work_dir=args.work_dir, max_iters=args.max_iters,
                    betas=args.betas, checkpoint=args.checkpoint,
                    seed=args.seed, cfg_options=args.cfg_options)
    return train_and_evaluate(cfg, num_vis=args.num_vis)


if __name__ == '__main__':
    main()
