"""Corruption benchmark (mPC, rPC) and Foggy Cityscapes beta sweep.

Follows MMDetection's ``tools/analysis_tools/test_robustness.py``
(Copyright (c) OpenMMLab, Apache-2.0): MMDet's ``Corrupt`` transform
(``imagecorruptions``) after the image loader, severities 0-5, results
stored in MMDet's format; it also runs configs without
``model.backbone.init_cfg`` (the demo) or without ``model.backbone``
(CBNet-DD), and tests the physical fog of Foggy Cityscapes next to the
synthetic one. See :mod:`cbnet_lab.robustness`.

Usage::

    python tools/analysis_tools/test_robustness.py CONFIG CHECKPOINT \
        [--corruptions weather] [--severities 0 1 2 3 4 5] \
        [--betas 0.005 0.01 0.02] [--out-dir work_dirs/robustness] \
        [--aggregate benchmark] [--num-images N] [--cfg-options ...]

``--num-images N`` tests the first N images under every corruption and
fog density, scored against their own ground truth only (the cut
annotation files go to ``{out-dir}/first_N_images/``).

Writes to ``--out-dir``:

* ``robustness_results.pkl``: ``{corruption: {severity: metrics}}``, the
  file MMDet's ``robustness_eval.py`` reads::

      python $(python -c "import mmdet, os; print(os.path.dirname(
          mmdet.__file__))")/.mim/tools/analysis_tools/robustness_eval.py \
          robustness_results.pkl --task bbox segm --prints P mPC rPC

* ``robustness.json`` (P, mPC, rPC per metric, per corruption and
  severity; the beta sweep) and ``robustness.md`` (the same as tables);
* ``fog_density.png``: box/mask AP and mIoU against fog density, the
  Foggy Cityscapes beta and the ``fog`` severity side by side.
"""
import argparse
import json
import os
import os.path as osp

from mmengine.config import Config, DictAction
from mmengine.fileio import dump

import cbnet_mmdet  # noqa: F401  (registers the components)
from cbnet_lab.config_edits import robustness_cfgs
from cbnet_lab.robustness import (SUMMARY_METRICS, plot_fog_density,
                                  resolve_corruptions, run_benchmark,
                                  summarize, to_markdown)
from cbnet_tools.markdown import markdown_table
from cbnet_tools.quick_eval import first_images_cfg


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description='Corruption robustness and fog-density sweep')
    parser.add_argument('config')
    parser.add_argument('checkpoint')
    parser.add_argument(
        '--corruptions', nargs='*', default=['weather'],
        help='corruption names or groups (benchmark, all, noise, blur, '
        'weather, digital, holdout); none (an empty list) for the beta '
        'sweep alone')
    parser.add_argument('--severities', type=int, nargs='+',
                        default=[0, 1, 2, 3, 4, 5])
    parser.add_argument('--betas', type=float, nargs='*', default=[],
                        help='Foggy Cityscapes betas (1/m) to test too')
    parser.add_argument('--aggregate', choices=['benchmark', 'all'],
                        default='benchmark',
                        help='mPC over the first 15 corruptions or all')
    parser.add_argument('--out-dir', default='work_dirs/robustness')
    parser.add_argument('--seed', type=int, default=0,
                        help='seed of the (random) corruptions')
    parser.add_argument('--num-images', type=int, metavar='N',
                        help='test the first N images only, scored against '
                        'their own ground truth')
    parser.add_argument('--cfg-options', nargs='+', action=DictAction,
                        help='override config keys')
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    cfg = Config.fromfile(args.config)
    if args.cfg_options:
        cfg.merge_from_dict(args.cfg_options)
    if args.num_images is not None:
        cfg = first_images_cfg(
            cfg, args.num_images,
            osp.join(args.out_dir, f'first_{args.num_images}_images'))
    cfg.randomness = dict(seed=args.seed)
    if any(s > 0 for s in args.severities) and 0 not in args.severities:
        # P (the clean score) is what mPC and rPC are relative to
        print('severity 0 (clean) added: P, mPC and rPC need it')
        args.severities = [0] + list(args.severities)
    os.makedirs(args.out_dir, exist_ok=True)
    run = run_benchmark(robustness_cfgs(
        cfg, args.checkpoint, args.out_dir,
        resolve_corruptions(args.corruptions), args.severities, args.betas))
    report = dict(config=args.config, checkpoint=args.checkpoint,
                  summaries={}, betas=run['betas'])
    tables = []
    if run['corruptions'] and 0 in args.severities and any(
            s > 0 for s in args.severities):
        dump(run['corruptions'],
             osp.join(args.out_dir, 'robustness_results.pkl'))
        clean = next(iter(run['corruptions'].values())).get(0, {})
        for label, key in SUMMARY_METRICS:
            if clean.get(key, -1) < 0:
                continue  # not computed by this config's evaluators
            summary = summarize(run['corruptions'], key, args.aggregate)
            report['summaries'][label] = summary
            tables.append(to_markdown(summary, label))
    if run['betas']:
        lines = markdown_table(
            ['beta (1/m)'] + [label for label, _ in SUMMARY_METRICS],
            [[f'{beta:g}'] + [
                '-' if metrics.get(key, -1) < 0 else
                f'{100 * metrics[key]:.1f}' for _, key in SUMMARY_METRICS
            ] for beta, metrics in sorted(run['betas'].items())])
        tables.append('Foggy Cityscapes (0: clear)\n\n' + '\n'.join(lines))
    markdown = '\n\n'.join(tables)
    print(markdown)
    with open(osp.join(args.out_dir, 'robustness.md'), 'w') as f:
        f.write(markdown + '\n')
    with open(osp.join(args.out_dir, 'robustness.json'), 'w') as f:
        json.dump(report, f, indent=1, default=float)
    if run['betas'] or 'fog' in run['corruptions']:
        png = plot_fog_density(
            run, osp.join(args.out_dir, 'fog_density.png'),
            title=osp.splitext(osp.basename(args.config))[0])
        print(f'fog density plot: {png}')
    return report


if __name__ == '__main__':
    main()
