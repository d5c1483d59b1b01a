"""Write the generated Cityscapes / Foggy Cityscapes stand-in dataset.

Usage::

    python tools/misc/generate_cityscapes_like.py data/cityscapes_like \
        [--num-train 40 --num-val 10 --size 256 512 --seed 0] [--convert] \
        [--density 1.0] [--min-height-px 8]

The layout is Cityscapes' (``leftImg8bit``, ``gtFine``,
``leftImg8bit_foggy``, plus ``depth`` in centimetres); ``--convert`` also
writes the COCO JSON under ``OUT_ROOT/annotations`` like
``tools/dataset_converters/cityscapes.py`` does for real data.
"""
import argparse

from cbnet_mmdet.datasets.cityscapes_paths import FOGGY_BETAS
from cbnet_mmdet.datasets.synthetic import generate_cityscapes_like


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description='Generate a seeded Cityscapes-like mini dataset')
    parser.add_argument('out_root', help='output dataset root')
    parser.add_argument('--num-train', type=int, default=40)
    parser.add_argument('--num-val', type=int, default=10)
    parser.add_argument(
        '--size', type=int, nargs=2, default=[256, 512],
        metavar=('H', 'W'), help='image height and width, pixels')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument(
        '--betas', type=float, nargs='+', default=list(FOGGY_BETAS),
        help='fog attenuation coefficients, 1/m')
    parser.add_argument('--nproc', type=int, default=1)
    parser.add_argument(
        '--density', type=float, default=1.0,
        help='scale of the mean object counts per image (1: about 20 '
        'instances, as Cityscapes)')
    parser.add_argument(
        '--min-height-px', type=float, default=8.0,
        help='objects shorter than this (pixels) are not drawn')
    parser.add_argument(
        '--convert', action='store_true',
        help='also write annotations/instancesonly_filtered_gtFine_*.json')
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    records = generate_cityscapes_like(
        args.out_root, num_train=args.num_train, num_val=args.num_val,
        img_size=tuple(args.size), seed=args.seed, betas=args.betas,
        nproc=args.nproc, density=args.density,
        min_height_px=args.min_height_px)
    for split, recs in records.items():
        n_inst = sum(len(r['instances']) for r in recs)
        print(f'{split}: {len(recs)} images, {n_inst} instances')
    if args.convert:
        from cbnet_mmdet.datasets.cityscapes_to_coco import convert
        convert(args.out_root, nproc=args.nproc)


if __name__ == '__main__':
    main()
