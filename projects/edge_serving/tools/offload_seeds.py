"""One offload table from several seeds of the edge model.

Usage::

    python projects/edge_serving/tools/offload_seeds.py \
        OUT/seed0/offload.json OUT/seed1/offload.json OUT/seed2/offload.json \
        [--names 0 1 2] --out-dir OUT

Each ``offload.json`` is ``offload_eval.py``'s record of one trained seed of
the local model over the same stream. Rows are lined up by rule and level
(the haze and confidence rules at default thresholds by decile); writes
``OUT/offload_seeds.json`` and ``OUT/offload_seeds.md`` (mean +- std over
the seeds) and prints the table.
"""
import argparse
import json
import os
import os.path as osp


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('records', nargs='+', help="offload_eval.py's "
                   'offload.json, one per seed of the local model')
    p.add_argument('--names', nargs='+',
                   help='a name per record (default: 0, 1, ...)')
    p.add_argument('--out-dir', required=True)
    args = p.parse_args(argv)
    if args.names and len(args.names) != len(args.records):
        p.error(f'--names gives {len(args.names)} names for '
                f'{len(args.records)} records')
    return args


def main(argv=None):
    args = parse_args(argv)
    from cbnet_serving.offload_seeds import combine, load, to_markdown
    table = combine(load(args.records), args.names)
    table['records'] = list(args.records)
    os.makedirs(args.out_dir, exist_ok=True)
    md = to_markdown(table)
    with open(osp.join(args.out_dir, 'offload_seeds.json'), 'w') as f:
        json.dump(table, f, indent=1)
    with open(osp.join(args.out_dir, 'offload_seeds.md'), 'w') as f:
        f.write(md)
    print(md)
    return table


if __name__ == '__main__':
    main()
