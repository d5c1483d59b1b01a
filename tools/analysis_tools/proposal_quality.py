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

Prints a markdown table and writes the figures as JSON.
"""
import argparse
import glob
import json
import os
import os.path as osp

import torch
from mmengine.config import Config
from mmengine.dataset import pseudo_collate
from mmengine.registry import init_default_scope

from cbnet_mmdet.utils.checkpoint_tools import last_checkpoint_in
from cbnet_mmdet.utils.markdown import markdown_table

RECALL_IOUS = (0.5, 0.7, 0.9)
POSITIVE_IOUS = (0.5, 0.6, 0.7)


def proposal_quality(model, dataset, max_images=None) -> dict:
    """Proposal statistics of ``model`` (eval mode) over ``dataset``."""
    from mmdet.structures.bbox import bbox_overlaps
    best_per_gt, best_per_proposal, counts = [], [], []
    num = len(dataset) if max_images is None else min(max_images,
                                                      len(dataset))
    with torch.no_grad():
        for i in range(num):
            data = model.data_preprocessor(pseudo_collate([dataset[i]]),
                                           False)
            sample = data['data_samples'][0]
            feats = model.extract_feat(data['inputs'])
            props = model.rpn_head.predict(
                feats, data['data_samples'], rescale=False)[0].bboxes
            gt = sample.gt_instances.bboxes
            gt = getattr(gt, 'tensor', gt).to(props)
            # GT boxes are in the original image; proposals in the resized
            sx, sy = sample.metainfo['scale_factor']
            gt = gt * gt.new_tensor([sx, sy, sx, sy])
            counts.append(len(props))
            ious = bbox_overlaps(gt, props)
            if len(gt) and len(props):
                best_per_gt.append(ious.max(1).values)
                best_per_proposal.append(ious.max(0).values)
            else:
                best_per_gt.append(props.new_zeros(len(gt)))
                best_per_proposal.append(props.new_zeros(len(props)))
    per_gt = torch.cat(best_per_gt) if best_per_gt else torch.zeros(0)
    per_prop = (torch.cat(best_per_proposal) if best_per_proposal else
                torch.zeros(0))

    def share(values, t):
        return float((values >= t).float().mean()) if len(values) else 0.

    return dict(
        images=num,
        gt_boxes=len(per_gt),
        proposals_per_image=sum(counts) / max(num, 1),
        recall={str(t): share(per_gt, t) for t in RECALL_IOUS},
        mean_best_iou=float(per_gt.mean()) if len(per_gt) else 0.,
        positive_share={str(t): share(per_prop, t) for t in POSITIVE_IOUS})


def to_markdown(results: dict) -> str:
    head = (['model', 'proposals / image'] +
            [f'recall@{t}' for t in RECALL_IOUS] + ['mean best IoU'] +
            [f'proposals IoU>={t}' for t in POSITIVE_IOUS])
    return '\n'.join(markdown_table(head, [
        [name, f"{r['proposals_per_image']:.0f}"] +
        [f"{r['recall'][str(t)]:.3f}" for t in RECALL_IOUS] +
        [f"{r['mean_best_iou']:.3f}"] +
        [f"{r['positive_share'][str(t)]:.3f}" for t in POSITIVE_IOUS]
        for name, r in results.items()
    ]))


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
        torch.set_num_threads(args.threads)
    import cbnet_mmdet  # noqa: F401  (registers the components)
    from mmdet.apis import init_detector
    from mmdet.registry import DATASETS
    init_default_scope('mmdet')
    names = args.names or default_names(args, pairs)
    if len(set(names)) != len(names):
        raise SystemExit(f'two models share a name in {names}: give --names')
    results = {}
    for name, (config, ckpt) in zip(names, pairs):
        cfg = Config.fromfile(config)
        dataset_cfg = cfg.test_dataloader.dataset
        if args.data_root:
            dataset_cfg.data_root = args.data_root
        model = init_detector(cfg, ckpt, device='cpu')
        results[name] = proposal_quality(model, DATASETS.build(dataset_cfg),
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
