"""Write the generated Cityscapes / Foggy Cityscapes stand-in dataset.

Usage::

    python tools/misc/generate_cityscapes_like.py data/cityscapes_like \
        [--num-train 40 --num-val 10 --size 256 512 --seed 0] [--convert] \
        [--density 1.0] [--min-height-px 8]
    # the benchmark of the comparison harness (compare_recipes.py
    # --preset bench); the options above override a preset's values
    python tools/misc/generate_cityscapes_like.py \
        data/cityscapes_like_bench --preset bench --nproc 2 --convert
    # keep what is there when it is the same dataset (tools/demo.sh);
    # a different one there is an error, not overwritten
    python tools/misc/generate_cityscapes_like.py \
        data/cityscapes_like_bench --preset bench --nproc 2 --convert --reuse

The layout is Cityscapes' (``leftImg8bit``, ``gtFine``,
``leftImg8bit_foggy``, plus ``depth`` in centimetres); ``--convert`` also
writes the COCO JSON under ``OUT_ROOT/annotations`` like
``tools/dataset_converters/cityscapes.py`` does for real data.
"""
import argparse
import os
import os.path as osp

from cbnet_mmdet.datasets.cityscapes_paths import FOGGY_BETAS
from cbnet_tools.synthetic import (generate_cityscapes_like, load_record,
                                   record_differences)
from cbnet_tools.synthetic.presets import DATA_PRESETS

#: Values without a preset (the generator's own defaults).
DEFAULTS = dict(num_train=40, num_val=10, img_size=(256, 512), density=1.0,
                min_height_px=8.0)


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description='Generate a seeded Cityscapes-like mini dataset')
    parser.add_argument('out_root', help='output dataset root')
    parser.add_argument(
        '--preset', choices=sorted(DATA_PRESETS),
        help='a named dataset: ' + '; '.join(
            f'{k}: {v}' for k, v in sorted(DATA_PRESETS.items())))
    parser.add_argument('--num-train', type=int,
                        help=f"default {DEFAULTS['num_train']}")
    parser.add_argument('--num-val', type=int,
                        help=f"default {DEFAULTS['num_val']}")
    parser.add_argument(
        '--size', type=int, nargs=2, metavar=('H', 'W'),
        help='image height and width, pixels (default 256 512)')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument(
        '--betas', type=float, nargs='+', default=list(FOGGY_BETAS),
        help='fog attenuation coefficients, 1/m')
    parser.add_argument('--nproc', type=int, default=1)
    parser.add_argument(
        '--density', type=float,
        help='scale of the mean object counts per image (default 1: about '
        '20 instances, as Cityscapes)')
    parser.add_argument(
        '--min-height-px', type=float,
        help='objects shorter than this (pixels) are not drawn (default 8)')
    parser.add_argument(
        '--convert', action='store_true',
        help='also write annotations/instancesonly_filtered_gtFine_*.json')
    parser.add_argument(
        '--reuse', action='store_true',
        help='if OUT_ROOT holds the dataset these options make (its '
        'generator_record.json), keep it; another dataset there is an '
        'error (without --reuse, files are overwritten)')
    args = parser.parse_args(argv)
    values = dict(DEFAULTS, **DATA_PRESETS.get(args.preset, {}))
    if args.size is not None:
        args.img_size = tuple(args.size)
    for key, value in values.items():
        if getattr(args, key, None) is None:
            setattr(args, key, value)
    return args


def _already_there(args) -> bool:
    """--reuse: True if OUT_ROOT holds this very dataset (its
    generator_record.json; whether it is converted is not asked here);
    SystemExit naming the difference if it holds anything else."""
    record = load_record(args.out_root)
    if record is None:
        if osp.isdir(args.out_root) and os.listdir(args.out_root):
            raise SystemExit(
                f'{args.out_root} is not empty and holds no generated '
                'dataset (no generator_record.json): remove it or give '
                'another folder')
        return False
    diff = record_differences(
        record, num_train=args.num_train, num_val=args.num_val,
        img_size=tuple(args.img_size), seed=args.seed, betas=args.betas,
        density=args.density, min_height_px=args.min_height_px)
    if diff:
        raise SystemExit(
            f'{args.out_root} holds another generated dataset ('
            + '; '.join(diff) + '): remove it or give another folder')
    print(f'{args.out_root}: already there (generator_record.json)')
    return True


def main(argv=None):
    args = parse_args(argv)
    reused = args.reuse and _already_there(args)
    if not reused:
        records = generate_cityscapes_like(
            args.out_root, num_train=args.num_train, num_val=args.num_val,
            img_size=tuple(args.img_size), seed=args.seed,
            betas=args.betas, nproc=args.nproc, density=args.density,
            min_height_px=args.min_height_px)
        for split, recs in records.items():
            n_inst = sum(len(r['instances']) for r in recs)
            print(f'{split}: {len(recs)} images, {n_inst} instances')
    # a kept dataset is converted again only if its annotations are missing
    converted = osp.isfile(osp.join(args.out_root, 'annotations',
                                    'instancesonly_filtered_gtFine_val.json'))
    if args.convert and not (reused and converted):
        from cbnet_tools.cityscapes_to_coco import convert
        convert(args.out_root, nproc=args.nproc)


if __name__ == '__main__':
    main()
