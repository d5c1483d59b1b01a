"""Convert Cityscapes ``gtFine`` instances to MMDetection's COCO JSON.

Usage::

    python tools/dataset_converters/cityscapes.py data/cityscapes \
        [-o data/cityscapes/annotations] [--nproc 8] [--splits train val]

Writes ``instancesonly_filtered_gtFine_{split}.json`` (the names MMDet's
Cityscapes configs read) for the 8 evaluated instance classes. The same
annotations serve Foggy Cityscapes (its images share the stems).
"""
import argparse

from cbnet_tools.cityscapes_to_coco import convert


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description='Convert Cityscapes annotations to COCO format')
    parser.add_argument('cityscapes_path', help='Cityscapes root folder')
    parser.add_argument(
        '-o', '--out-dir', help='output folder (default: ROOT/annotations)')
    parser.add_argument('--img-dir', default='leftImg8bit')
    parser.add_argument('--gt-dir', default='gtFine')
    parser.add_argument(
        '--splits', nargs='+', default=['train', 'val'],
        help='splits to convert (the test split has no public labels)')
    parser.add_argument('--nproc', default=1, type=int,
                        help='worker processes')
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    written = convert(args.cityscapes_path, args.out_dir, args.splits,
                      args.nproc, args.img_dir, args.gt_dir)
    for split, path in written.items():
        print(f'{split}: {path}')


if __name__ == '__main__':
    main()
