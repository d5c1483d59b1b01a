"""Regenerate the results tables of the docs from their JSON records.

Every ``<!-- table: COMMAND -->`` region of README.md, docs/,
configs/*/README.md and projects/*/README.md gets what its command prints
from committed records (cbnet_lab/doc_tables.py): ``compare_recipes.py
... --report-only ...`` (the recipe comparisons), ``offload_seeds.py``
(the edge model's offload tables) or ``record_table.py KIND RECORD``
(speed, kernel, backbone, proposal and model-index records); every
command runs once, all in one process::

    python tools/misc/update_doc_tables.py            # rewrite the tables
    python tools/misc/update_doc_tables.py --check    # exit 1 if stale
    python tools/misc/update_doc_tables.py docs/robustness.md
"""
import argparse
import os.path as osp
import sys

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('docs', nargs='*',
                        help='pages relative to the repository root '
                        '(default: every page with tables)')
    parser.add_argument('--check', action='store_true',
                        help='write nothing; exit 1 naming every table '
                        'that regenerating would change')
    args = parser.parse_args(argv)
    for doc in args.docs:
        if not osp.isfile(osp.join(ROOT, doc)):
            parser.error(f'no such page: {doc} (give it relative to '
                         f'{ROOT})')
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    sys.path.insert(0, ROOT)
    from cbnet_lab.doc_tables import update_docs
    try:
        stale = update_docs(ROOT, args.docs or None, check=args.check)
    except (ValueError, RuntimeError) as err:
        print(f'update_doc_tables: {err}', file=sys.stderr)
        return 2
    for region in stale:
        verb = 'is stale' if args.check else 'rewritten'
        print(f'{region.doc}:{region.line}: {verb}')
    if args.check and stale:
        print('run python tools/misc/update_doc_tables.py to regenerate '
              'them', file=sys.stderr)
        return 1
    print(f'{len(stale)} table(s) {"stale" if args.check else "rewritten"}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
