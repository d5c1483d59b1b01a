"""Draw a dataset's ground truth after its pipeline, paired sets included.

Follows MMDetection's ``tools/analysis_tools/browse_dataset.py``
(Copyright (c) OpenMMLab, Apache-2.0): the dataset of the config is built
with its pipeline and every item's boxes and masks are drawn with the
config's visualiser. A paired CBNet-DD item (6 channels: foggy + clear,
``CBNetLoadPairedImageFromFile``) is drawn as two panels, foggy | clear,
with the same annotations, which shows that both got the same crop/flip.

Usage::

    python tools/analysis_tools/browse_dataset.py CONFIG \
        [--split train|val|test] [--output-dir DIR] [--max-items N] \
        [--not-show] [--show-interval 2] [--cfg-options ...]
"""
import argparse
import os.path as osp

import mmcv
import numpy as np
from mmdet.models.utils import mask2ndarray
from mmdet.registry import DATASETS, VISUALIZERS
from mmdet.structures.bbox import BaseBoxes
from mmengine.config import Config, DictAction
from mmengine.registry import init_default_scope
from mmengine.utils import ProgressBar

import cbnet_mmdet  # noqa: F401  (registers the components)


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description='Browse a dataset')
    parser.add_argument('config', help='config file path')
    parser.add_argument('--split', choices=['train', 'val', 'test'],
                        default='train', help='which dataloader\'s dataset')
    parser.add_argument('--output-dir', default=None,
                        help='save the drawings there (no display needed)')
    parser.add_argument('--max-items', type=int, default=None,
                        help='stop after this many items')
    parser.add_argument('--not-show', action='store_true')
    parser.add_argument('--show-interval', type=float, default=2,
                        help='seconds each drawing is shown')
    parser.add_argument('--cfg-options', nargs='+', action=DictAction,
                        help='override config keys')
    return parser.parse_args(argv)


def panels_of(inputs) -> list:
    """RGB ``uint8[H, W, 3]`` panels of an item's ``inputs``.

    Args:
        inputs (Tensor): ``Tensor[C, H, W]`` in the loader's BGR order; C
            is 3, or 6 for a paired item (foggy channels 0-2, clear 3-5).

    Returns:
        list[np.ndarray]: one panel, or two (foggy, clear).

    Raises:
        ValueError: another number of channels.
    """
    img = inputs.permute(1, 2, 0).numpy()
    if img.shape[2] not in (3, 6):
        raise ValueError(f'cannot draw an image with {img.shape[2]} '
                         f'channels (3, or 6 for a foggy+clear pair)')
    return [
        np.ascontiguousarray(img[..., c:c + 3][..., ::-1])
        for c in range(0, img.shape[2], 3)
    ]


def ground_truth(data_sample):
    """The sample with boxes as tensors and masks as bool arrays."""
    data_sample = data_sample.numpy()
    gt = data_sample.gt_instances
    if isinstance(gt.get('bboxes', None), BaseBoxes):
        gt.bboxes = gt.bboxes.tensor
    if gt.get('masks', None) is not None:
        gt.masks = mask2ndarray(gt.masks).astype(bool)
    data_sample.gt_instances = gt
    return data_sample


def main(argv=None):
    args = parse_args(argv)
    cfg = Config.fromfile(args.config)
    if args.cfg_options:
        cfg.merge_from_dict(args.cfg_options)
    init_default_scope(cfg.get('default_scope', 'mmdet'))
    dataset = DATASETS.build(cfg[f'{args.split}_dataloader'].dataset)
    visualizer = VISUALIZERS.build(cfg.visualizer)
    visualizer.dataset_meta = dataset.metainfo

    count = len(dataset) if args.max_items is None else min(
        args.max_items, len(dataset))
    progress = ProgressBar(count)
    written = []
    for i in range(count):
        item = dataset[i]
        sample = ground_truth(item['data_samples'])
        drawn = []
        for panel in panels_of(item['inputs']):
            visualizer.add_datasample(
                'gt', panel, sample, draw_pred=False, show=False)
            drawn.append(visualizer.get_image())
        canvas = np.concatenate(drawn, axis=1)
        name = osp.basename(sample.img_path)
        out_file = None
        if args.output_dir is not None:
            out_file = osp.join(args.output_dir, f'{i:05d}_{name}')
            written.append(out_file)
        if not args.not_show:
            visualizer.show(canvas, win_name=name,
                            wait_time=args.show_interval)
        if out_file:
            mmcv.imwrite(canvas[..., ::-1], out_file)
        progress.update()
    return written


if __name__ == '__main__':
    main()
