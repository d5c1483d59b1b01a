"""Draw a model's masks and boxes on clear and foggy images, side by side.

Usage::

    python tools/misc/draw_predictions.py CONFIG CHECKPOINT IMG [IMG ...] \
        --out work_dirs/demo/predictions.png [--score-thr THR]

Each image is drawn with MMDet's ``DetLocalVisualizer`` (masks, boxes,
class names and scores); the panels are stacked into one PNG, one row per
image. A clear ``*_leftImg8bit.png`` is paired with its foggy twins when
``--betas`` is given, so a row shows the same scene in clear and in fog.
Each panel is titled above the picture with its condition (``clear``,
``beta 0.01``...; the file name when no ``--betas`` is given) and the
score the predictions are drawn from.

Predictions are drawn from the score the config's own evaluation paints
masks from (the ``score_thr`` of its ``CBNetInstanceMIoUMetric``: 0.1 in
the demo configs, where a short-trained cascade rarely scores above 0.3,
0.5 in the paper configs; MMDet's 0.3 for a config without that metric),
unless ``--score-thr`` says otherwise; the threshold used is printed.
"""
import argparse
import inspect
import os
import os.path as osp
from typing import Tuple

import mmcv
import numpy as np
from mmdet.apis import inference_detector
from mmdet.registry import VISUALIZERS

import cbnet_mmdet  # noqa: F401  (registers the components)
from cbnet_mmdet.datasets.cityscapes_paths import foggy_path
from cbnet_mmdet.evaluation.metrics import CBNetInstanceMIoUMetric
from cbnet_mmdet.utils.checkpoint.fit import init_checked_detector


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('config')
    parser.add_argument('checkpoint')
    parser.add_argument('images', nargs='+',
                        help='clear image files, or folders (every image '
                        'file directly inside, sorted)')
    parser.add_argument('--betas', type=float, nargs='*', default=[],
                        help='also draw the foggy twins with these betas')
    parser.add_argument('--out', required=True, help='output PNG')
    parser.add_argument(
        '--score-thr', type=float, default=None,
        help='draw predictions scoring at least this (default: the '
        'score_thr of the config\'s CBNetInstanceMIoUMetric)')
    parser.add_argument('--device', default='cpu')
    args = parser.parse_args(argv)
    if args.score_thr is not None and not 0 <= args.score_thr <= 1:
        parser.error(f'--score-thr must be in [0, 1], got {args.score_thr}')
    bad = [b for b in args.betas if not b > 0]
    if bad:
        parser.error(f'--betas must be > 0 (fog densities, 1/m), got {bad}')
    if osp.splitext(args.out)[1].lower() not in IMAGE_EXTENSIONS:
        parser.error(f'--out {args.out}: give an image file name (.png, '
                     '.jpg)')
    return args


#: What a folder's images are (lower-case suffixes).
IMAGE_EXTENSIONS = ('.jpg', '.jpeg', '.png', '.bmp', '.tif', '.tiff',
                    '.webp')


def image_files(paths):
    """``paths`` with each folder replaced by its image files (sorted).

    Raises:
        FileNotFoundError: A path that does not exist.
        ValueError: A folder without image files.
    """
    files = []
    for path in paths:
        if osp.isdir(path):
            found = sorted(
                osp.join(path, name) for name in os.listdir(path)
                if osp.splitext(name)[1].lower() in IMAGE_EXTENSIONS and
                osp.isfile(osp.join(path, name)))
            if not found:
                raise ValueError(
                    f'{path} is a folder with no image file directly inside '
                    f'({", ".join(IMAGE_EXTENSIONS)})')
            files += found
        elif not osp.exists(path):
            raise FileNotFoundError(f'no such image or folder: {path}')
        else:
            files.append(path)
    return files


def read_image(path):
    """The RGB image at ``path``.

    Raises:
        ValueError: The file is not an image OpenCV can decode (a text
            file, a truncated or damaged image), naming it.
    """
    try:
        img = mmcv.imread(path, channel_order='rgb')
    except Exception as err:  # OpenCV's errors name no file
        raise ValueError(f'{path}: not a readable image ({err})') from None
    if img is None or img.size == 0:
        raise ValueError(f'{path}: not a readable image (OpenCV decodes '
                         'nothing: not an image, or a truncated/damaged '
                         'file)')
    return img


#: MMDet's drawing threshold, for configs without CBNetInstanceMIoUMetric.
MMDET_SCORE_THR = 0.3


def evaluation_score_thr(cfg) -> Tuple[float, str]:
    """The score from which the config's evaluation paints masks.

    Args:
        cfg (Config): The model's config.

    Returns:
        tuple[float, str]: The threshold and where it comes from.
    """
    evaluators = cfg.get('test_evaluator') or []
    if isinstance(evaluators, dict):
        evaluators = [evaluators]
    for evaluator in evaluators:
        if evaluator.get('type') in ('CBNetInstanceMIoUMetric',
                                     'mmdet.CBNetInstanceMIoUMetric'):
            default = inspect.signature(
                CBNetInstanceMIoUMetric).parameters['score_thr'].default
            thr = evaluator.get('score_thr', default)
            return float(thr), 'the score_thr of its CBNetInstanceMIoUMetric'
    return MMDET_SCORE_THR, 'MMDetection\'s default'


#: Height (px) of the title band above each panel.
TITLE_HEIGHT = 22


def titled(panel: np.ndarray, title: str) -> np.ndarray:
    """``panel`` (RGB) under a white band with ``title`` in black."""
    import cv2
    band = np.full((TITLE_HEIGHT, panel.shape[1], 3), 255, np.uint8)
    cv2.putText(band, title, (4, TITLE_HEIGHT - 7), cv2.FONT_HERSHEY_SIMPLEX,
                0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([band, panel], axis=0)


def draw_rows(model, rows, score_thr, titles=None):
    """Draw every image of every row; returns the stacked RGB array.

    Args:
        titles (list[str], optional): One title per column (the
            conditions), drawn above each panel with the score threshold;
            default the file names.
    """
    visualizer = VISUALIZERS.build(model.cfg.visualizer)
    visualizer.dataset_meta = model.dataset_meta
    drawn_rows = []
    for row in rows:
        panels = []
        for path in row:
            if not osp.isfile(path):
                raise FileNotFoundError(f'no image {path}')
            img = read_image(path)
            result = inference_detector(model, path)
            visualizer.add_datasample(
                osp.basename(path), img, data_sample=result, draw_gt=False,
                show=False, pred_score_thr=score_thr)
            title = (titles[len(panels)] if titles else osp.basename(path))
            panels.append(titled(visualizer.get_image(),
                                 f'{title}, scores >= {score_thr:g}'))
        drawn_rows.append(np.concatenate(panels, axis=1))
    width = max(r.shape[1] for r in drawn_rows)
    drawn_rows = [
        np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)))
        for r in drawn_rows
    ]
    return np.concatenate(drawn_rows, axis=0)


def main(argv=None):
    args = parse_args(argv)
    # every image found and readable before the model is built
    images = image_files(args.images)
    for path in images:
        read_image(path)
    # a checkpoint that does not fill the model is refused, not drawn
    model = init_checked_detector(args.config, args.checkpoint,
                                  device=args.device)
    rows = [[img] + [foggy_path(img, b) for b in args.betas]
            for img in images]
    if args.score_thr is None:
        score_thr, source = evaluation_score_thr(model.cfg)
    else:
        score_thr, source = args.score_thr, '--score-thr'
    print(f'drawing predictions scoring >= {score_thr} ({source})')
    titles = ['clear'] + [f'beta {b:g}' for b in args.betas] \
        if args.betas else None
    canvas = draw_rows(model, rows, score_thr, titles)
    os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
    mmcv.imwrite(canvas[..., ::-1], args.out)
    print(f'predictions drawn: {args.out} ({len(rows)} scenes, '
          f'{1 + len(args.betas)} conditions each)')


if __name__ == '__main__':
    main()
