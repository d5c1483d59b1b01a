"""Strip a training checkpoint for release and put its hash in the name.

Derived from MMDetection's ``tools/model_converters/publish_model.py``
(Copyright (c) OpenMMLab, Apache-2.0); see
:func:`cbnet_mmdet.utils.checkpoint.files.publish_checkpoint` for what
differs.

Usage::

    python tools/model_converters/publish_model.py \
        work_dirs/cbnet/epoch_12.pth cbnet_mit-b5_cityscapes.pth
    # -> cbnet_mit-b5_cityscapes-1a2b3c4d.pth (meta + state_dict only)
"""
import argparse

import cbnet_mmdet  # noqa: F401  (weights-only allow-list, registries)
from cbnet_mmdet.utils.checkpoint.files import (PUBLISH_KEYS,
                                                publish_checkpoint)


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description='Process a checkpoint to be published')
    parser.add_argument('in_file', help='input checkpoint filename')
    parser.add_argument('out_file', help='output checkpoint filename')
    parser.add_argument('--save-keys', nargs='+', default=list(PUBLISH_KEYS),
                        help='top-level keys kept in the published file')
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    final = publish_checkpoint(args.in_file, args.out_file, args.save_keys)
    print(f'The published model is saved at {final}.')
    return final


if __name__ == '__main__':
    main()
