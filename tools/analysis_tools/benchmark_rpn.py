"""Proposal recall and speed: ``CBNetCascadeRPNHead`` vs MMDet's ``RPNHead``.

Both heads are trained the same way (same seed, data order, iterations,
optimiser, tiny from-scratch ResNet-18 + ``CBNetNASFPN`` trunk) inside
MMDet's ``RPN`` detector on a COCO-format dataset, then evaluated on its val
split with COCO proposal recall (pycocotools ``COCOeval``, ``useCats=0``,
through MMDet's ``CocoMetric(metric='proposal')``), and the forward time of
each head alone is measured on fixed trunk features.

Usage::

    python tools/misc/generate_cityscapes_like.py data/cityscapes --convert
    python tools/analysis_tools/benchmark_rpn.py [--data-root data/cityscapes]
        [--iters 60] [--scale 384 192] [--out work_dirs/benchmark_rpn.json]

``--synthetic`` first writes a simple stand-in set (textured boxes and
ellipses of the 8 Cityscapes classes on a noisy background, COCO JSON in the
same layout) under ``--data-root``, for when the generated Cityscapes-like
set is not available.

Prints a markdown table and writes the figures as JSON.
"""
import argparse
import copy
import json
import os
import os.path as osp
import time

import cv2
import numpy as np
import torch
from mmdet.evaluation import CocoMetric
from mmdet.registry import DATASETS, MODELS
from mmdet.utils import register_all_modules
from mmengine.config import ConfigDict
from mmengine.dataset import DefaultSampler, pseudo_collate
from mmengine.optim import OptimWrapper
from torch.utils.data import DataLoader

import cbnet_mmdet  # noqa: F401  (registers the components)

TRAIN_ANN = 'annotations/instancesonly_filtered_gtFine_train.json'
VAL_ANN = 'annotations/instancesonly_filtered_gtFine_val.json'
PROPOSAL_NUMS = (100, 300, 1000)  # COCOeval's summary needs three


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description='Compare CBNetCascadeRPNHead with RPNHead')
    parser.add_argument('--data-root', default='data/cityscapes')
    parser.add_argument('--train-ann', default=TRAIN_ANN)
    parser.add_argument('--val-ann', default=VAL_ANN)
    parser.add_argument('--train-img', default='leftImg8bit/train/')
    parser.add_argument('--val-img', default='leftImg8bit/val/')
    parser.add_argument('--iters', type=int, default=60,
                        help='training iterations of each head')
    parser.add_argument('--warmup', type=int, default=10,
                        help='linear learning-rate warm-up iterations')
    parser.add_argument('--batch-size', type=int, default=2)
    parser.add_argument('--lr', type=float, default=0.01)
    parser.add_argument(
        '--scale', type=int, nargs=2, default=[384, 192],
        metavar=('W', 'H'), help='resize scale (keep ratio), pixels')
    parser.add_argument('--width', type=int, default=32,
                        help='neck / head channels')
    parser.add_argument('--time-runs', type=int, default=20)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--heads', nargs='+', default=['RPNHead', 'CRPN'],
                        choices=['RPNHead', 'CRPN'])
    parser.add_argument('--out', default='work_dirs/benchmark_rpn.json')
    parser.add_argument(
        '--synthetic', type=int, nargs=2, metavar=('N_TRAIN', 'N_VAL'),
        help='write a synthetic set of this many images under --data-root')
    return parser.parse_args(argv)


def make_synthetic(root, num_train, num_val, hw=(256, 512), seed=0):
    """Write a COCO-format stand-in set: 3..12 filled boxes / ellipses per
    image (sides 10..160 px, aspect 1:3..3:1, textured), 8 classes.

    Args:
        root (str): Output root; images go to ``leftImg8bit/{split}/syn``
            and JSON to ``TRAIN_ANN`` / ``VAL_ANN``.
        num_train (int): Training images.
        num_val (int): Validation images.
        hw (tuple[int, int]): Image height and width, pixels.
        seed (int): Random seed.
    """
    from mmdet.datasets import CityscapesDataset
    classes = CityscapesDataset.METAINFO['classes']
    rng = np.random.RandomState(seed)
    h, w = hw
    for split, num, ann in (('train', num_train, TRAIN_ANN),
                            ('val', num_val, VAL_ANN)):
        img_dir = osp.join(root, 'leftImg8bit', split, 'syn')
        os.makedirs(img_dir, exist_ok=True)
        images, annots = [], []
        for i in range(num):
            low = cv2.resize(
                rng.randint(0, 255, (h // 32, w // 32, 3)).astype(np.uint8),
                (w, h), interpolation=cv2.INTER_CUBIC)
            img = np.clip(low + rng.normal(0, 12, (h, w, 3)), 0, 255)
            img = img.astype(np.uint8)
            for _ in range(rng.randint(3, 13)):
                side = float(np.exp(rng.uniform(np.log(10), np.log(160))))
                aspect = float(np.exp(rng.uniform(np.log(1 / 3), np.log(3))))
                bw = max(4, min(w - 2, int(side * np.sqrt(aspect))))
                bh = max(4, min(h - 2, int(side / np.sqrt(aspect))))
                x0, y0 = rng.randint(0, w - bw), rng.randint(0, h - bh)
                color = tuple(int(c) for c in rng.randint(0, 255, 3))
                if rng.rand() < 0.5:
                    cv2.rectangle(img, (x0, y0), (x0 + bw - 1, y0 + bh - 1),
                                  color, -1)
                else:
                    cv2.ellipse(img, (x0 + bw // 2, y0 + bh // 2),
                                (bw // 2, bh // 2), 0, 0, 360, color, -1)
                annots.append(
                    dict(id=len(annots) + 1, image_id=i,
                         category_id=int(rng.randint(1, len(classes) + 1)),
                         bbox=[x0, y0, bw, bh], area=bw * bh, iscrowd=0))
            name = f'syn/{split}_{i:04d}.png'
            cv2.imwrite(osp.join(root, 'leftImg8bit', split, name), img)
            images.append(dict(id=i, file_name=name, height=h, width=w))
        os.makedirs(osp.dirname(osp.join(root, ann)), exist_ok=True)
        with open(osp.join(root, ann), 'w') as f:
            json.dump(
                dict(images=images, annotations=annots,
                     categories=[
                         dict(id=k + 1, name=c) for k, c in enumerate(classes)
                     ]), f)


def trunk_cfg(width):
    """Tiny from-scratch trunk shared by both heads."""
    return dict(
        data_preprocessor=dict(
            type='DetDataPreprocessor',
            mean=[123.675, 116.28, 103.53],
            std=[58.395, 57.12, 57.375],
            bgr_to_rgb=True,
            pad_size_divisor=32),
        backbone=dict(
            type='ResNet',
            depth=18,
            base_channels=16,
            out_indices=(0, 1, 2, 3),
            norm_cfg=dict(type='BN'),
            init_cfg=None),
        neck=dict(
            type='CBNetNASFPN', in_channels=[16, 32, 64, 128],
            out_channels=width, stack_times=1))


def head_cfg(name, width):
    """``rpn_head``, ``train_cfg`` and ``test_cfg`` of an ``RPN`` detector.

    Both keep k = 1000 proposals; each keeps its MMDet NMS threshold
    (0.7 for RPN, 0.8 for Cascade RPN).
    """
    if name == 'CRPN':
        return dict(
            rpn_head=dict(type='CBNetCascadeRPNHead', in_channels=width,
                          feat_channels=width),
            train_cfg=None,  # the head's per-stage defaults
            test_cfg=None)  # the head's default: k = 1000
    return dict(
        rpn_head=dict(
            type='RPNHead',
            in_channels=width,
            feat_channels=width,
            anchor_generator=dict(
                type='AnchorGenerator', scales=[8], ratios=[0.5, 1.0, 2.0],
                strides=[4, 8, 16, 32, 64]),
            bbox_coder=dict(
                type='DeltaXYWHBBoxCoder', target_means=[0.0] * 4,
                target_stds=[1.0] * 4),
            loss_cls=dict(
                type='CrossEntropyLoss', use_sigmoid=True, loss_weight=1.0),
            loss_bbox=dict(type='L1Loss', loss_weight=1.0)),
        train_cfg=dict(
            assigner=dict(
                type='MaxIoUAssigner', pos_iou_thr=0.7, neg_iou_thr=0.3,
                min_pos_iou=0.3, ignore_iof_thr=-1),
            sampler=dict(
                type='RandomSampler', num=256, pos_fraction=0.5,
                neg_pos_ub=-1, add_gt_as_proposals=False),
            allowed_border=-1, pos_weight=-1, debug=False),
        test_cfg=dict(
            nms_pre=2000, max_per_img=1000,
            nms=dict(type='nms', iou_threshold=0.7), min_bbox_size=0))


def build_rpn(name, width):
    """MMDet's ``RPN`` detector (the head is its ``bbox_head``), initialised.

    ``MODELS.build`` leaves every layer at PyTorch's default init; the
    heads' own initialisation (the focal prior p = 0.01 of the CRPN's
    objectness, normal(0, 0.01) convolutions) only runs in
    ``init_weights()``.
    """
    parts = head_cfg(name, width)
    model = MODELS.build(
        ConfigDict(
            type='RPN',
            rpn_head=parts['rpn_head'],
            train_cfg=dict(rpn=parts['train_cfg']),
            test_cfg=dict(rpn=parts['test_cfg']),
            **trunk_cfg(width)))
    model.init_weights()
    return model


def build_loader(args, split, seed):
    scale = tuple(args.scale)
    train = split == 'train'
    pipeline = [
        dict(type='LoadImageFromFile'),
        dict(type='LoadAnnotations', with_bbox=True),
        dict(type='Resize', scale=scale, keep_ratio=True),
    ]
    if train:
        pipeline.append(dict(type='RandomFlip', prob=0.5))
    pipeline.append(dict(type='PackDetInputs'))
    ann = args.train_ann if train else args.val_ann
    ann_path = osp.join(args.data_root, ann)
    if not osp.isfile(ann_path):
        raise FileNotFoundError(
            f'{ann_path} not found: generate the dataset with '
            '`python tools/misc/generate_cityscapes_like.py '
            f'{args.data_root} --convert` or pass --data-root')
    dataset = DATASETS.build(
        dict(
            type='CityscapesDataset',
            data_root=args.data_root,
            ann_file=ann,
            data_prefix=dict(img=args.train_img if train else args.val_img),
            filter_cfg=dict(filter_empty_gt=train),
            test_mode=not train,
            pipeline=pipeline))
    sampler = DefaultSampler(dataset, shuffle=train, seed=seed)
    loader = DataLoader(
        dataset,
        batch_size=args.batch_size if train else 1,
        sampler=sampler,
        collate_fn=pseudo_collate,
        num_workers=0)
    return dataset, loader


def train(model, loader, iters, lr, warmup):
    optim = OptimWrapper(
        torch.optim.SGD(model.parameters(), lr=lr, momentum=0.9,
                        weight_decay=1e-4),
        clip_grad=dict(max_norm=35, norm_type=2))
    model.train()
    it, start = 0, time.perf_counter()
    while it < iters:
        for data in loader:
            for group in optim.param_groups:  # linear warm-up
                group['lr'] = lr * min(1.0, (it + 1) / max(1, warmup))
            log = model.train_step(data, optim)
            it += 1
            if it % 10 == 0 or it == iters:
                print(f'  iter {it}/{iters} loss {log["loss"].item():.4f}')
            if it == iters:
                print('  last losses: ' + ', '.join(
                    f'{k}={v.item():.4f}' for k, v in log.items()))
            if it == iters:
                break
    return time.perf_counter() - start


@torch.no_grad()
def evaluate(model, loader, ann_file):
    model.eval()
    metric = CocoMetric(ann_file=ann_file, metric='proposal',
                        proposal_nums=PROPOSAL_NUMS)
    metric.dataset_meta = loader.dataset.metainfo
    num_props = []
    for data in loader:
        outputs = model.val_step(data)
        num_props += [len(o.pred_instances) for o in outputs]
        metric.process(data, [o.to_dict() for o in outputs])
    results = metric.evaluate(len(loader.dataset))
    return {
        f'AR@{n}': float(results[f'coco/AR@{n}'])
        for n in (100, 1000)
    }, float(np.mean(num_props))


@torch.no_grad()
def time_heads(models, loader, runs):
    """Median seconds of each ``bbox_head.predict`` on fixed trunk features.

    The heads are timed in turns (one call each per round), so that a
    change of machine load hits all of them alike.
    """
    data = next(iter(loader))
    inputs = {}
    for name, model in models.items():
        model.eval()
        batch = model.data_preprocessor(data, False)
        inputs[name] = (model.extract_feat(batch['inputs']),
                        batch['data_samples'])
        model.bbox_head.predict(*inputs[name])  # warm-up
    times = {name: [] for name in models}
    for _ in range(runs):
        for name, model in models.items():
            start = time.perf_counter()
            model.bbox_head.predict(*inputs[name])
            times[name].append(time.perf_counter() - start)
    hw = tuple(batch['inputs'].shape[-2:])
    return {name: float(np.median(t)) for name, t in times.items()}, hw


def main(argv=None):
    args = parse_args(argv)
    register_all_modules()
    if args.synthetic:
        make_synthetic(args.data_root, *args.synthetic, seed=args.seed)
    torch.set_num_threads(max(1, min(2, os.cpu_count() or 1)))
    rows, models = [], {}
    for name in args.heads:
        torch.manual_seed(args.seed)
        np.random.seed(args.seed)
        model = build_rpn(name, args.width)
        _, train_loader = build_loader(args, 'train', args.seed)
        _, val_loader = build_loader(args, 'val', args.seed)
        print(f'{name}: training {args.iters} iterations')
        train_s = train(model, train_loader, args.iters, args.lr,
                        args.warmup)
        ar, mean_props = evaluate(
            model, val_loader, osp.join(args.data_root, args.val_ann))
        models[name] = model
        rows.append(
            dict(head=name, **ar, mean_proposals=mean_props,
                 train_s=train_s,
                 params=sum(p.numel()
                            for p in model.bbox_head.parameters())))
    fwd_s, hw = time_heads(models, val_loader, args.time_runs)
    for row in rows:
        row.update(head_forward_ms=1000 * fwd_s[row['head']], input_hw=hw)
    print('\n| head | AR@100 | AR@1000 | proposals/img | head forward, '
          'median (ms) | head params | train (s) |')
    print('|---|---|---|---|---|---|---|')
    for r in rows:
        print(f"| {r['head']} | {r['AR@100']:.3f} | {r['AR@1000']:.3f} | "
              f"{r['mean_proposals']:.0f} | {r['head_forward_ms']:.1f} | "
              f"{r['params']} | {r['train_s']:.0f} |")
    out = dict(args=vars(copy.deepcopy(args)), results=rows,
               device='cpu', torch_threads=torch.get_num_threads())
    os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(out, f, indent=2)
    print(f'written {args.out}')


if __name__ == '__main__':
    main()
