"""What the RPN of a trained model hands its RoI heads, on the test split.

For each ``CONFIG CHECKPOINT`` pair, the test-time proposals of every test
image (the config's ``test_cfg.rpn``, in the resized image's coordinates)
against the ground-truth boxes scaled the same way:

* recall at IoU 0.5 / 0.7 / 0.9 (share of GT boxes with a proposal at or
  above it) and the mean best IoU per GT box: how well objects are found;
* the share of proposals whose best IoU with a GT box is at least 0.5 /
  0.6 / 0.7: how many of the RoIs the box stages see are positives at the
  cascade's thresholds (the rest are background to them).

Usage::

    python tools/analysis_tools/proposal_quality.py \\
        [CONFIG CHECKPOINT ...] [--runs WORK_DIR ...] [--names A B ...] \\
        [--data-root DIR] [--max-images N] [--out work_dirs/proposals.json]

``--runs`` takes training folders (a comparison harness run, a ``tools/
train.py`` work dir): the one config in it and its last checkpoint.

Prints a markdown table and writes the figures as JSON; the work is
``cbnet_lab.proposal_quality``'s.
"""
import argparse
import glob
import json
import os
import os.path as osp

from cbnet_lab.proposal_quality import evaluate, to_markdown
from cbnet_mmdet.utils.checkpoint.files import last_checkpoint_in


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('pairs', nargs='*', metavar='CONFIG CHECKPOINT')
    parser.add_argument('--runs', nargs='+', default=[],
                        help='training folders: their config and last '
                        'checkpoint')
    parser.add_argument('--names', nargs='+', help='one name per model')
    parser.add_argument('--data-root', help="replaces the test dataset's")
    parser.add_argument('--max-images', type=int)
    parser.add_argument('--threads', type=int, default=None)
    parser.add_argument('--out', default='work_dirs/proposal_quality.json')
    args = parser.parse_args(argv)
    if len(args.pairs) % 2:
        parser.error('give CONFIG CHECKPOINT pairs')
    if not args.pairs and not args.runs:
        parser.error('nothing to measure: give CONFIG CHECKPOINT pairs or '
                     '--runs')
    return args


def models_of(args) -> list:
    """(config, checkpoint) of each model asked for; SystemExit with the
    reason when a file is missing."""
    pairs = list(zip(args.pairs[::2], args.pairs[1::2]))
    for run in args.runs:
        configs = glob.glob(osp.join(run, '*.py'))
        ckpt, _ = last_checkpoint_in(run)
        if len(configs) != 1 or ckpt is None:
            raise SystemExit(
                f'--runs {run}: needs one config (*.py) and a '
                f'last_checkpoint; found {len(configs)} configs, checkpoint '
                f'{ckpt}')
        pairs.append((configs[0], ckpt))
    for _, ckpt in pairs:
        if not osp.isfile(ckpt):
            raise SystemExit(f'checkpoint not found: {ckpt}')
    if args.names and len(args.names) != len(pairs):
        raise SystemExit(f'--names: {len(args.names)} names for '
                         f'{len(pairs)} models')
    return pairs


def default_names(args, pairs) -> list:
    """A config's name for a pair, ``parent/folder`` for a run (seeds of
    one config differ by folder)."""
    runs = [osp.join(*osp.normpath(r).split(osp.sep)[-2:])
            for r in args.runs]
    return [osp.splitext(osp.basename(c))[0]
            for c, _ in pairs[:len(pairs) - len(runs)]] + runs


def main(argv=None):
    args = parse_args(argv)
    pairs = models_of(args)
    if args.threads:
        import torch
        torch.set_num_threads(args.threads)
    names = args.names or default_names(args, pairs)
    if len(set(names)) != len(names):
        raise SystemExit(f'two models share a name in {names}: give --names')
    results = {}
    for name, (config, ckpt) in zip(names, pairs):
        results[name] = evaluate(config, ckpt, args.data_root,
                                 args.max_images)
        print(f'{name}: {results[name]}', flush=True)
    os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(dict(models=dict(zip(names, pairs)), results=results), f,
                  indent=1)
    print(to_markdown(results))
    return results


if __name__ == '__main__':
    main()
