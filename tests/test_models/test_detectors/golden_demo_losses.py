"""Seeded loss dict of the whole demo CBNet, and how to regenerate it.

The demo model (``configs/demo/cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-
like.py``: MiT-B0 with CSPE and Mish, NAS-FPN, Cascade RPN, 3 cascade box
stages, boundary-aware mask head), built and initialised with seed 0, in
training mode, gets one fixed batch (two 64x128 images of drawn
rectangles / ellipses of the 8 classes, made here with numpy, independent
of the dataset generator) and its ``loss`` dict is compared with
:data:`GOLDEN` by ``test_demo_golden_losses.py``.

When a deliberate change of the forward logic or of the recipe (loss
weights, normalisations...) changes these numbers, regenerate them::

    OMP_NUM_THREADS=1 python tests/test_models/test_detectors/\\
golden_demo_losses.py --print     # show the new values
    OMP_NUM_THREADS=1 python tests/test_models/test_detectors/\\
golden_demo_losses.py --update    # rewrite GOLDEN in this file

and say in the commit why they changed.
"""
import argparse
import os.path as osp
import re
import sys

import numpy as np
import torch

REPO = osp.dirname(osp.dirname(osp.dirname(osp.dirname(
    osp.abspath(__file__)))))
DEMO = osp.join(REPO, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
#: (H, W) of the fixed batch's images, pixels.
SIZE = (64, 128)

# --- GOLDEN (rewritten by --update) ---
GOLDEN = {
    's0.acc': 5.078125,
    's0.loss_bbox': 0.29308468103408813,
    's0.loss_cls': 5.42244815826416,
    's0.loss_rpn_reg': 5.1113200187683105,
    's1.acc': 0.390625,
    's1.loss_bbox': 0.011736929416656494,
    's1.loss_cls': 2.749049663543701,
    's1.loss_rpn_cls': 1.128219485282898,
    's1.loss_rpn_reg': 4.587836265563965,
    's2.acc': 0.78125,
    's2.loss_bbox': 9.61959926826239e-07,
    's2.loss_cls': 1.4108834266662598,
    's2.loss_mask': 1.2925761938095093,
}
# --- end GOLDEN ---


def fixed_batch(seed: int = 0, num_imgs: int = 2) -> dict:
    """Two BGR images with 3 filled shapes each and their annotations.

    Returns:
        dict: ``inputs`` (list of uint8 ``Tensor[3, H, W]``) and
        ``data_samples`` (``DetDataSample`` with ``gt_instances``: boxes
        in pixels, labels in ``[0, 8)``, ``BitmapMasks``).
    """
    from mmdet.structures import DetDataSample
    from mmdet.structures.mask import BitmapMasks
    from mmengine.structures import InstanceData
    rng = np.random.default_rng(seed)
    h, w = SIZE
    yy, xx = np.mgrid[:h, :w]
    inputs, samples = [], []
    for _ in range(num_imgs):
        img = rng.integers(0, 60, (3, h, w)).astype(np.uint8)
        masks, labels, boxes = [], [], []
        for k in range(3):
            x1, y1 = int(rng.integers(0, w // 2)), int(rng.integers(0, h // 2))
            x2 = min(x1 + int(rng.integers(16, w // 2)), w)
            y2 = min(y1 + int(rng.integers(12, h // 2)), h)
            if k % 2:
                cx, cy = (x1 + x2 - 1) / 2, (y1 + y2 - 1) / 2
                m = (((xx - cx) / ((x2 - x1) / 2))**2 +
                     ((yy - cy) / ((y2 - y1) / 2))**2) <= 1
            else:
                m = (xx >= x1) & (xx < x2) & (yy >= y1) & (yy < y2)
            img[:, m] = rng.integers(100, 255, (3, 1))
            masks.append(m)
            labels.append(int(rng.integers(0, 8)))
            ys, xs = np.nonzero(m)
            boxes.append([xs.min(), ys.min(), xs.max() + 1, ys.max() + 1])
        sample = DetDataSample(metainfo=dict(
            img_shape=SIZE, ori_shape=SIZE, scale_factor=(1., 1.)))
        sample.gt_instances = InstanceData(
            bboxes=torch.tensor(boxes, dtype=torch.float32),
            labels=torch.tensor(labels),
            masks=BitmapMasks(np.stack(masks).astype(np.uint8), h, w))
        inputs.append(torch.from_numpy(img))
        samples.append(sample)
    return dict(inputs=inputs, data_samples=samples)


def demo_losses() -> dict:
    """The demo model's seeded loss dict on :func:`fixed_batch`.

    Computed on ONE torch thread, whatever the machine: the thread count
    changes float rounding (how reductions are split, and which elements
    an element-wise kernel computes in its scalar tail, e.g. ``exp``), and
    one-ulp differences move the demo's cascade losses by up to 1e-4
    relative (an RoI crossing an IoU threshold), above the tolerance.

    Returns:
        dict[str, float]: Every entry of ``model.loss`` (losses and
        accuracies), as Python floats (sums for list entries).
    """
    from mmdet.registry import MODELS
    from mmengine.config import Config
    from mmengine.registry import init_default_scope

    import cbnet_mmdet  # noqa: F401  (registers the components)
    init_default_scope('mmdet')
    cfg = Config.fromfile(DEMO)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        torch.manual_seed(0)
        model = MODELS.build(cfg.model)
        model.init_weights()
        model.train()
        torch.manual_seed(1)  # the samplers' draws
        data = model.data_preprocessor(fixed_batch(), True)
        losses = model(**data, mode='loss')
    finally:
        torch.set_num_threads(threads)
    out = {}
    for key, value in sorted(losses.items()):
        if isinstance(value, (list, tuple)):
            value = sum(v.sum() for v in value)
        out[key] = float(value.detach().sum())
    return out


def _format(losses: dict) -> str:
    lines = ['GOLDEN = {']
    lines += [f'    {k!r}: {v!r},' for k, v in losses.items()]
    lines.append('}')
    return '\n'.join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument('--print', action='store_true',
                       help='print the current values as GOLDEN = {...}')
    group.add_argument('--update', action='store_true',
                       help='rewrite GOLDEN in this file')
    args = parser.parse_args(argv)
    text = _format(demo_losses())
    print(text)
    if args.update:
        path = osp.abspath(__file__)
        with open(path) as f:
            source = f.read()
        source = re.sub(
            r'(# --- GOLDEN \(rewritten by --update\) ---\n).*?'
            r'(# --- end GOLDEN ---)',
            lambda m: m.group(1) + text + '\n' + m.group(2), source,
            flags=re.S)
        with open(path, 'w') as f:
            f.write(source)
        print(f'written to {path}')


if __name__ == '__main__':
    sys.path.insert(0, REPO)  # the checkout's package, not an installed one
    main()
