"""Draw a model's masks and boxes on clear and foggy images, side by side.

Usage::

    python tools/misc/draw_predictions.py CONFIG CHECKPOINT IMG [IMG ...] \
        --out work_dirs/demo/predictions.png [--score-thr 0.3]

Each image is drawn with MMDet's ``DetLocalVisualizer`` (masks, boxes,
class names and scores); the panels are stacked into one PNG, one row per
image. A clear ``*_leftImg8bit.png`` is paired with its foggy twins when
``--betas`` is given, so a row shows the same scene in clear and in fog.
"""
import argparse
import os
import os.path as osp

import mmcv
import numpy as np
from mmdet.apis import inference_detector, init_detector
from mmdet.registry import VISUALIZERS

import cbnet_mmdet  # noqa: F401  (registers the components)
from cbnet_mmdet.datasets.cityscapes_paths import foggy_path


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('config')
    parser.add_argument('checkpoint')
    parser.add_argument('images', nargs='+', help='clear image files')
    parser.add_argument('--betas', type=float, nargs='*', default=[],
                        help='also draw the foggy twins with these betas')
    parser.add_argument('--out', required=True, help='output PNG')
    parser.add_argument('--score-thr', type=float, default=0.3)
    parser.add_argument('--device', default='cpu')
    return parser.parse_args(argv)


def draw_rows(model, rows, score_thr):
    """Draw every image of every row; returns the stacked RGB array."""
    visualizer = VISUALIZERS.build(model.cfg.visualizer)
    visualizer.dataset_meta = model.dataset_meta
    drawn_rows = []
    for row in rows:
        panels = []
        for path in row:
            if not osp.isfile(path):
                raise FileNotFoundError(f'no image {path}')
            img = mmcv.imread(path, channel_order='rgb')
            result = inference_detector(model, path)
            visualizer.add_datasample(
                osp.basename(path), img, data_sample=result, draw_gt=False,
                show=False, pred_score_thr=score_thr)
            panels.append(visualizer.get_image())
        drawn_rows.append(np.concatenate(panels, axis=1))
    width = max(r.shape[1] for r in drawn_rows)
    drawn_rows = [
        np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)))
        for r in drawn_rows
    ]
    return np.concatenate(drawn_rows, axis=0)


def main(argv=None):
    args = parse_args(argv)
    model = init_detector(args.config, args.checkpoint, device=args.device)
    rows = [[img] + [foggy_path(img, b) for b in args.betas]
            for img in args.images]
    canvas = draw_rows(model, rows, args.score_thr)
    os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
    mmcv.imwrite(canvas[..., ::-1], args.out)
    print(f'predictions drawn: {args.out} ({len(rows)} scenes, '
          f'{1 + len(args.betas)} conditions each)')


if __name__ == '__main__':
    main()
