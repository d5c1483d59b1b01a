"""Convert a SegFormer MiT checkpoint to ``CBNetMiT``'s parameter layout.

``init_cfg=dict(type='Pretrained', checkpoint=...)`` already reads the
official ``mit_b*.pth`` files; converting once saves the conversion at
every start and drops the ImageNet head explicitly (listed on stdout).

Usage::

    python tools/model_converters/mit2cbnet.py mit_b5.pth mit_b5_cbnet.pth
"""
import argparse
import os
import os.path as osp

import torch
from mmengine.runner import CheckpointLoader

from cbnet_mmdet.models.backbones import convert_mit_checkpoint
from cbnet_mmdet.utils import mmengine_safe_globals


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description='Convert official/mmseg MiT weights for CBNetMiT')
    parser.add_argument('src', help='source checkpoint (path or URL)')
    parser.add_argument('dst', help='output .pth path')
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    with mmengine_safe_globals():  # weights-only, MMEngine's log objects
        checkpoint = CheckpointLoader.load_checkpoint(
            args.src, map_location='cpu')
    state_dict, ignored, layout = convert_mit_checkpoint(checkpoint)
    out_dir = osp.dirname(osp.abspath(args.dst))
    os.makedirs(out_dir, exist_ok=True)
    torch.save(dict(state_dict=state_dict, meta=dict(source_layout=layout)),
               args.dst)
    print(f'{layout} layout -> {args.dst}: {len(state_dict)} tensors')
    if ignored:
        print('not converted (no backbone parameter): ' + ', '.join(ignored))
    return state_dict, ignored


if __name__ == '__main__':
    main()
