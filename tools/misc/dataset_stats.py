"""Print the statistics of COCO instance annotation files.

Usage::

    python tools/misc/dataset_stats.py \
        data/cityscapes/annotations/instancesonly_filtered_gtFine_train.json \
        [more.json ...] [--json stats.json]

For each file: images, instances per image, per-class counts and the area
histogram (COCO small / medium / large, finer pixel bins, relative size)
as markdown tables (see ``cbnet_tools/coco_statistics.py``).
``--json`` also writes them, keyed by file.
"""
import argparse
import json

from cbnet_tools.coco_statistics import (coco_statistics,
                                         format_statistics, load_coco)


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description='Statistics of COCO instance annotation files')
    parser.add_argument('ann_files', nargs='+', help='COCO JSON files')
    parser.add_argument('--json', help='also write the statistics here')
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    out = {}
    for path in args.ann_files:
        out[path] = coco_statistics(load_coco(path))
        print(format_statistics(out[path], path))
    if args.json:
        with open(args.json, 'w') as f:
            json.dump(out, f, indent=1)
    return out


if __name__ == '__main__':
    main()
