"""Export the student of a CBNet-DD checkpoint as a plain CBNet checkpoint.

The result loads like any detector checkpoint: with the CBNet config the
student was built from (for the shipped CBNet-DD config:
``configs/cbnet/cbnet_mit-b5_nasfpn-crpn_8xb1-12e_foggy-cityscapes.py``),
or alone, since the detector's config replaces the distiller's in
``meta['cfg']``::

    python tools/model_converters/extract_student.py \
        work_dirs/cbnet-dd/epoch_12.pth cbnet-dd_student.pth [--publish]
    python -c "from mmdet.apis import DetInferencer; \
        DetInferencer(weights='cbnet-dd_student.pth')('img.png')"

``--which teacher`` exports the EMA teacher instead; ``--publish`` adds the
SHA-256 prefix to the name as ``publish_model.py`` does.
"""
import argparse

import cbnet_mmdet  # noqa: F401  (weights-only allow-list, registries)
from cbnet_mmdet.utils.checkpoint.files import extract_detector


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description='CBNet-DD checkpoint -> plain CBNet checkpoint')
    parser.add_argument('in_file', help='CBNetDistiller checkpoint')
    parser.add_argument('out_file', help='output checkpoint filename')
    parser.add_argument('--which', choices=['student', 'teacher'],
                        default='student')
    parser.add_argument('--publish', action='store_true',
                        help='put the sha256 prefix into the file name')
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    out = extract_detector(args.in_file, args.out_file, args.which,
                           hashed=args.publish)
    print(f'{args.which} of {args.in_file} saved at {out}.')
    return out


if __name__ == '__main__':
    main()
