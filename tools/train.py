"""Train a detector with cbnet_mmdet components registered.

Follows MMDetection's ``tools/train.py`` (Copyright (c) OpenMMLab,
Apache-2.0): same arguments and runner set-up.

Usage::

    python tools/train.py CONFIG [--work-dir DIR] [--resume [CKPT]] [--amp]
                         [--tensorboard] [--strict]
    bash tools/dist_train.sh CONFIG NUM_GPUS [...]   # torch.distributed
    mim train cbnet_mmdet CONFIG [...]               # from an installed wheel
"""
import argparse
import os
import os.path as osp

import torch
from mmengine.config import Config, DictAction
from mmengine.registry import RUNNERS
from mmengine.runner import Runner

import cbnet_mmdet  # noqa: F401  (registers the components)
from cbnet_tools.cpu_distributed import (init_gloo_process_group,
                                         use_gloo_on_cpu)
from cbnet_tools.pretrained import require_pretrained
from mmdet.utils import setup_cache_size_limit_of_dynamo


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description='Train a detector')
    parser.add_argument('config', help='train config file path')
    parser.add_argument('--work-dir', help='where logs and checkpoints go')
    parser.add_argument(
        '--amp', action='store_true', help='mixed-precision training')
    parser.add_argument(
        '--auto-scale-lr',
        action='store_true',
        help='scale the lr by total batch size / base_batch_size')
    parser.add_argument(
        '--resume',
        nargs='?',
        type=str,
        const='auto',
        help='resume from CKPT, or from the latest checkpoint in the work '
        'dir when no path is given')
    parser.add_argument(
        '--tensorboard',
        action='store_true',
        help='also write the logged scalars for TensorBoard (adds '
        'MMEngine\'s TensorboardVisBackend to visualizer.vis_backends)')
    parser.add_argument(
        '--strict',
        action='store_true',
        help='stop with an error on any annotation the datasets would '
        'drop (unknown category, box outside its image, ...) instead of '
        'dropping it with a warning')
    parser.add_argument(
        '--cfg-options',
        nargs='+',
        action=DictAction,
        help='override config keys, e.g. train_cfg.max_epochs=1')
    parser.add_argument(
        '--launcher',
        choices=['none', 'pytorch', 'slurm', 'mpi'],
        default='none',
        help='job launcher')
    # torch.distributed.launch passes --local_rank, torchrun sets
    # LOCAL_RANK and older launchers pass --local-rank: accept all.
    parser.add_argument('--local_rank', '--local-rank', type=int, default=0)
    args = parser.parse_args(argv)
    if 'LOCAL_RANK' not in os.environ:
        os.environ['LOCAL_RANK'] = str(args.local_rank)
    return args


def build_cfg(args) -> Config:
    cfg = Config.fromfile(args.config)
    cfg.launcher = args.launcher
    if args.cfg_options is not None:
        cfg.merge_from_dict(args.cfg_options)
    if args.work_dir is not None:
        cfg.work_dir = args.work_dir
    elif cfg.get('work_dir', None) is None:
        cfg.work_dir = osp.join('./work_dirs',
                                osp.splitext(osp.basename(args.config))[0])
    if args.amp:
        cfg.optim_wrapper.type = 'AmpOptimWrapper'
        cfg.optim_wrapper.loss_scale = 'dynamic'
    if args.auto_scale_lr:
        if 'base_batch_size' not in cfg.get('auto_scale_lr', {}):
            raise KeyError('--auto-scale-lr needs `auto_scale_lr = dict('
                           'base_batch_size=...)` in the config')
        cfg.auto_scale_lr.enable = True
    if args.tensorboard:
        add_tensorboard_backend(cfg)
    if args.resume == 'auto':
        cfg.resume = True
        cfg.load_from = None
    elif args.resume is not None:
        if not osp.isfile(args.resume):
            raise FileNotFoundError(f'--resume: no checkpoint {args.resume}')
        cfg.resume = True
        cfg.load_from = args.resume
    if args.strict:
        for key in ('train_dataloader', 'val_dataloader', 'test_dataloader'):
            set_strict(cfg.get(key) or {})
    if args.launcher != 'none' and not torch.cuda.is_available():
        use_gloo_on_cpu(cfg)
    return cfg


def add_tensorboard_backend(cfg: Config) -> None:
    """Append ``TensorboardVisBackend`` to ``cfg.visualizer.vis_backends``
    (a list of dicts, which ``--cfg-options`` cannot pass), unless it is
    there already."""
    visualizer = cfg.get('visualizer')
    if visualizer is None:
        raise KeyError('--tensorboard needs a `visualizer` in the config')
    backends = list(visualizer.get('vis_backends') or [])
    if not any(b.get('type') in ('TensorboardVisBackend',
                                 'mmengine.TensorboardVisBackend')
               for b in backends):
        backends.append(dict(type='TensorboardVisBackend'))
    visualizer.vis_backends = backends


def set_strict(node) -> None:
    """Set ``strict=True`` on every CBNet dataset config under ``node`` (a
    dataloader config; wrappers' ``dataset`` / ``datasets`` included)."""
    if isinstance(node, (list, tuple)):
        for child in node:
            set_strict(child)
    elif isinstance(node, dict):
        kind = node.get('type')
        if isinstance(kind, str) and kind.split('.')[-1].startswith(
                'CBNet') and kind.endswith('Dataset'):
            node['strict'] = True
        for key in ('dataset', 'datasets'):
            set_strict(node.get(key))


def main(argv=None):
    args = parse_args(argv)
    setup_cache_size_limit_of_dynamo()
    cfg = build_cfg(args)
    # a missing pretrained trunk: an error naming the command that fetches
    # it, before anything is built
    require_pretrained(cfg)
    init_gloo_process_group(cfg)
    # as MMDetection's: the config names the runner (ours: CBNetRunner,
    # configs/_base_/default_runtime.py)
    if 'runner_type' not in cfg:
        runner = Runner.from_cfg(cfg)
    else:
        runner = RUNNERS.build(cfg)
    runner.train()


if __name__ == '__main__':
    main()
