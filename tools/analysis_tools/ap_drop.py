"""AP and mIoU drop of one checkpoint from Cityscapes to Foggy Cityscapes.

Usage::

    python tools/analysis_tools/ap_drop.py CONFIG CHECKPOINT \
        [--betas 0.005 0.01 0.02] [--out-dir work_dirs/ap_drop] \
        [--cfg-options test_dataloader.dataset.data_root=data/cityscapes/]

Tests the checkpoint on clear val, then on foggy val for each beta (same
annotations), prints the paper's Table 2 as markdown (box AP, mask AP, mask
AP50, mIoU and their drops, in percent) and writes ``ap_drop.json`` and
``ap_drop.md`` to ``--out-dir``.

Real fog. ``--real-fog DIR`` tests the checkpoint of any detector config
on the val split of a VOC real-fog folder instead (box AP; masks are
ignored; no betas), e.g. DAWN's fog photos or RTTS (PNG images)::

    python tools/analysis_tools/ap_drop.py CONFIG CHECKPOINT \
        --real-fog data/dawn_fog
    python tools/analysis_tools/ap_drop.py CONFIG CHECKPOINT \
        --real-fog data/rtts --cfg-options \
        test_dataloader.dataset.img_suffix=.png

A config written for real data (its ``data_root`` a folder of
``test_conditions`` in ``configs/experiments/_base_/presets.py``, which
names the condition: DAWN's ``real fog``, the box-only recipes of
``configs/realfog/``; ``coco street``) is tested on its own test set only
(no betas); a single condition has no reference to drop from, so its table
has no drop columns.

Quick evaluation. ``--num-images N`` tests the first N images of each
condition, scored against their own ground truth only (the cut annotation
files go to ``{out-dir}/first_N_images/``).
"""
import argparse
import json
import os
import os.path as osp

from mmengine.config import Config, DictAction

import cbnet_mmdet  # noqa: F401  (registers the components)
from cbnet_lab.ap_drop import ap_drop, to_markdown
from cbnet_lab.config_edits import (REAL_FOG, ap_drop_cfgs, default_betas,
                                    real_fog_cfg)
from cbnet_lab.sets import data_condition
from cbnet_tools.quick_eval import first_images_cfg


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description='Clear vs foggy evaluation of one checkpoint')
    parser.add_argument('config')
    parser.add_argument('checkpoint')
    parser.add_argument('--betas', type=float, nargs='*', default=None,
                        help='fog attenuation coefficients, 1/m (default '
                        '0.02; none for a real-data config)')
    parser.add_argument('--out-dir', default='work_dirs/ap_drop')
    parser.add_argument('--real-fog', metavar='DIR',
                        help='test on the val split of this VOC real-fog '
                        'folder (boxes only) instead')
    parser.add_argument('--num-images', type=int, metavar='N',
                        help='test the first N images only, scored against '
                        'their own ground truth')
    parser.add_argument('--cfg-options', nargs='+', action=DictAction,
                        help='override config keys')
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    cfg = Config.fromfile(args.config)
    # real data, by the folder the config is written for (or --real-fog's)
    condition = data_condition(cfg.get('data_root'))
    if args.real_fog:
        cfg, condition = real_fog_cfg(cfg, args.real_fog), REAL_FOG
    if args.cfg_options:
        cfg.merge_from_dict(args.cfg_options)
    os.makedirs(args.out_dir, exist_ok=True)
    if args.num_images is not None:
        cfg = first_images_cfg(
            cfg, args.num_images,
            osp.join(args.out_dir, f'first_{args.num_images}_images'))
    betas = default_betas(condition) if args.betas is None else args.betas
    table = ap_drop(ap_drop_cfgs(cfg, args.checkpoint, args.out_dir, betas,
                                 condition=condition))
    md = to_markdown(table)
    print(md)
    with open(osp.join(args.out_dir, 'ap_drop.md'), 'w') as f:
        f.write(md + '\n')
    with open(osp.join(args.out_dir, 'ap_drop.json'), 'w') as f:
        json.dump(table, f, indent=1)
    return table


if __name__ == '__main__':
    main()
