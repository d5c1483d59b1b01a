"""Evaluate a checkpoint with cbnet_mmdet components registered.

Follows MMDetection's ``tools/test.py`` (Copyright (c) OpenMMLab,
Apache-2.0): same arguments and runner set-up.

Usage::

    python tools/test.py CONFIG CHECKPOINT [--work-dir DIR] [--out RESULTS.pkl]
        [--num-images N]
    bash tools/dist_test.sh CONFIG CHECKPOINT NUM_GPUS [...]
    mim test cbnet_mmdet CONFIG --checkpoint CHECKPOINT

``--num-images N`` tests the first N test images and scores them against
their own ground truth only (the cut annotation files are written to
``{work_dir}/first_N_images/``; cbnet_tools.quick_eval). A config whose
``test_dataloader.dataset.indices`` is set while an evaluator reads a
whole ``ann_file`` is refused: its AP would count the objects of the
images not tested as missed.
"""
import argparse
import os
import os.path as osp

import torch
from mmengine.config import Config, DictAction
from mmengine.registry import RUNNERS
from mmengine.runner import Runner

import cbnet_mmdet  # noqa: F401  (registers the components)
from cbnet_mmdet.utils.checkpoint.fit import require_checkpoint_fit
from cbnet_tools.cpu_distributed import (init_gloo_process_group,
                                         use_gloo_on_cpu)
from cbnet_tools.quick_eval import check_subset_scoring, first_images_cfg
from mmdet.utils import setup_cache_size_limit_of_dynamo


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description='Test (and eval) a model')
    parser.add_argument('config', help='test config file path')
    parser.add_argument('checkpoint', help='checkpoint file')
    parser.add_argument('--work-dir', help='where the metrics are written')
    parser.add_argument(
        '--out', type=str, help='dump predictions to a pickle file')
    parser.add_argument(
        '--show-dir', help='save drawn predictions into this folder')
    parser.add_argument(
        '--num-images', type=int, metavar='N',
        help='test the first N images only, scored against their own '
        'ground truth')
    parser.add_argument(
        '--cfg-options',
        nargs='+',
        action=DictAction,
        help='override config keys, e.g. test_evaluator.beta=0.02')
    parser.add_argument(
        '--launcher',
        choices=['none', 'pytorch', 'slurm', 'mpi'],
        default='none',
        help='job launcher')
    parser.add_argument('--local_rank', '--local-rank', type=int, default=0)
    args = parser.parse_args(argv)
    if 'LOCAL_RANK' not in os.environ:
        os.environ['LOCAL_RANK'] = str(args.local_rank)
    return args


def build_cfg(args) -> Config:
    if not osp.isfile(args.checkpoint):
        raise FileNotFoundError(f'no checkpoint {args.checkpoint}')
    cfg = Config.fromfile(args.config)
    cfg.launcher = args.launcher
    if args.cfg_options is not None:
        cfg.merge_from_dict(args.cfg_options)
    if args.work_dir is not None:
        cfg.work_dir = args.work_dir
    elif cfg.get('work_dir', None) is None:
        cfg.work_dir = osp.join('./work_dirs',
                                osp.splitext(osp.basename(args.config))[0])
    if args.num_images is not None:
        cfg = first_images_cfg(
            cfg, args.num_images,
            osp.join(cfg.work_dir, f'first_{args.num_images}_images'))
    check_subset_scoring(cfg)
    cfg.load_from = args.checkpoint
    # a checkpoint that does not fill the model is refused, not evaluated
    # with random weights where it does not fit
    require_checkpoint_fit(cfg)
    if args.show_dir:
        vis = cfg.default_hooks.get('visualization')
        if vis is None:
            raise KeyError('--show-dir needs a `visualization` hook in '
                           'default_hooks')
        vis.draw = True
        vis.test_out_dir = args.show_dir
    if args.out is not None:
        if not args.out.endswith(('.pkl', '.pickle')):
            raise ValueError('--out must end with .pkl or .pickle')
        cfg.test_evaluator = _as_list(cfg.test_evaluator) + [
            dict(type='DumpDetResults', out_file_path=args.out)
        ]
    if args.launcher != 'none' and not torch.cuda.is_available():
        use_gloo_on_cpu(cfg)
    return cfg


def _as_list(x):
    return list(x) if isinstance(x, (list, tuple)) else [x]


def main(argv=None):
    args = parse_args(argv)
    setup_cache_size_limit_of_dynamo()
    cfg = build_cfg(args)
    init_gloo_process_group(cfg)
    if 'runner_type' not in cfg:
        runner = Runner.from_cfg(cfg)
    else:
        runner = RUNNERS.build(cfg)
    return runner.test()


if __name__ == '__main__':
    main()
