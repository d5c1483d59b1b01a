"""Malformed-input sweep: mutated annotations and images through the
dataset, the training pipeline and one training step of the demo CBNet.

Each variant is the training split of a Cityscapes-like COCO dataset
(first ``--images`` images) with ONE random mutation: of the annotation
JSON (keys removed, wrong types, degenerate or out-of-image boxes, broken
polygons/RLE, unknown categories, dangling ids, invalid JSON ...) or of one
image (truncated, random bytes, empty, grey/16-bit/RGBA, 1x1 ...). The
variant is then read with ``CBNetCityscapesDataset`` and the demo config's
training pipeline (at ``--scale``), collated, and put through one training
step (forward, backward; no optimiser step, so every variant sees the same
weights). Outcomes:

* ``ok``: trained, all losses and gradients finite;
* ``clear error``: ``FileNotFoundError`` / ``ValueError`` / ``KeyError`` /
  ``TypeError`` raised by the package's own code (a check of
  ``cbnet_mmdet``, not a library error that happens to print a path) AND
  naming the mutated file (the image, or the annotation file);
* ``crash``: anything else (other exceptions, library errors, errors that
  name no file, non-finite losses or gradients) - listed with the mutation
  to reproduce.

Usage::

    python tools/analysis_tools/fuzz_inputs.py [--data-root DIR]
        [--variants 300] [--seed 0] [--out work_dirs/fuzz_inputs.json]

Without ``--data-root`` a tiny set (4 + 3 images at 128x256) is generated
in a temporary folder. Prints a markdown table per mutation and writes the
counts and every crash as JSON.
"""
import argparse
import copy
import json
import os
import os.path as osp
import shutil
import tempfile
import time
import traceback
from collections import Counter, defaultdict
from typing import Callable, Dict, List, Tuple

import cv2
import numpy as np
import torch
from mmdet.registry import DATASETS, MODELS
from mmengine.config import Config
from mmengine.dataset import pseudo_collate
from mmengine.registry import init_default_scope

import cbnet_mmdet  # noqa: F401  (registers the components)

REPO = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
PACKAGE_DIR = osp.dirname(osp.abspath(cbnet_mmdet.__file__)) + os.sep
DEMO = osp.join(REPO, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
ANN = osp.join('annotations', 'instancesonly_filtered_gtFine_train.json')
CLEAR_TYPES = (FileNotFoundError, ValueError, KeyError, TypeError)

# -- mutations --------------------------------------------------------------
# A JSON mutation takes (coco dict, rng) and edits it in place; an image
# mutation takes (original image path, output path, rng) and writes a file.


def _ann(coco, rng):
    anns = coco['annotations']
    return anns[int(rng.integers(len(anns)))]


def _box(value):
    def mutate(coco, rng):
        a = _ann(coco, rng)
        x, y, w, h = a['bbox']
        a['bbox'] = value(x, y, w, h, rng)
    return mutate


def _drop(key, where):
    def mutate(coco, rng):
        if where == 'top':
            coco.pop(key, None)
        else:
            for item in coco[where]:
                item.pop(key, None)
    return mutate


def _set(where, key, value):
    def mutate(coco, rng):
        items = coco[where]
        item = items[int(rng.integers(len(items)))]
        item[key] = value(item, rng) if callable(value) else value
    return mutate


def _all_crowd(coco, rng):
    for a in coco['annotations']:
        a['iscrowd'] = 1


def _no_annotations(coco, rng):
    coco['annotations'] = []


def _dup_image_id(coco, rng):
    coco['images'][1]['id'] = coco['images'][0]['id']


def _many_tiny(coco, rng):
    img = coco['images'][0]
    for i in range(200):
        x, y = float(rng.uniform(0, img['width'] - 2)), float(
            rng.uniform(0, img['height'] - 2))
        coco['annotations'].append(
            dict(id=10**6 + i, image_id=img['id'], category_id=26,
                 iscrowd=0, area=1.0, bbox=[x, y, 1.0, 1.0],
                 segmentation=[[x, y, x + 1, y, x + 1, y + 1]]))


JSON_MUTATIONS: Dict[str, Callable] = {
    'bbox_negative_size': _box(lambda x, y, w, h, r: [x, y, -w, -h]),
    'bbox_zero_size': _box(lambda x, y, w, h, r: [x, y, 0.0, 0.0]),
    'bbox_outside_image': _box(lambda x, y, w, h, r: [5000., 5000., w, h]),
    'bbox_partly_outside': _box(lambda x, y, w, h, r: [-20., -20., w + 40,
                                                       h + 40]),
    'bbox_nan': _box(lambda x, y, w, h, r: [float('nan'), y, w, h]),
    'bbox_inf': _box(lambda x, y, w, h, r: [x, y, float('inf'), h]),
    'bbox_wrong_length': _box(lambda x, y, w, h, r: [x, y, w]),
    'bbox_string': _box(lambda x, y, w, h, r: 'abc'),
    'bbox_missing': _set('annotations', 'bbox', None),
    'segm_empty_list': _set('annotations', 'segmentation', []),
    'segm_two_points': _set('annotations', 'segmentation',
                            [[1.0, 1.0, 5.0, 5.0]]),
    'segm_odd_length': _set('annotations', 'segmentation',
                            [[1.0, 1.0, 9.0, 1.0, 9.0]]),
    'segm_rle_wrong_size': _set(
        'annotations', 'segmentation',
        dict(size=[7, 9], counts='0`0')),
    'segm_rle_garbage': _set('annotations', 'segmentation',
                             dict(size=[128, 256], counts='!!!!')),
    'segm_outside_image': _set(
        'annotations', 'segmentation',
        [[5000.0, 5000.0, 5010.0, 5000.0, 5010.0, 5010.0]]),
    'category_unknown': _set('annotations', 'category_id', 999),
    'category_string': _set('annotations', 'category_id', 'car'),
    'image_id_dangling': _set('annotations', 'image_id', 12345),
    'iscrowd_all': _all_crowd,
    'no_annotations': _no_annotations,
    'duplicate_image_id': _dup_image_id,
    'image_size_wrong': _set('images', 'width', 17),
    'image_size_zero': _set('images', 'height', 0),
    'file_name_missing_file': _set('images', 'file_name',
                                   'nowhere/none_leftImg8bit.png'),
    'file_name_empty': _set('images', 'file_name', ''),
    'key_images_missing': _drop('images', 'top'),
    'key_annotations_missing': _drop('annotations', 'top'),
    'key_categories_missing': _drop('categories', 'top'),
    'image_key_id_missing': _drop('id', 'images'),
    'ann_key_image_id_missing': _drop('image_id', 'annotations'),
    'many_tiny_instances': _many_tiny,
    'json_truncated': lambda coco, rng: None,  # cut when written
}


def _truncate(src, dst, rng):
    data = open(src, 'rb').read()
    open(dst, 'wb').write(data[:int(rng.integers(1, len(data)))])


def _random_bytes(src, dst, rng):
    open(dst, 'wb').write(rng.bytes(int(rng.integers(1, 4096))))


def _flip_bytes(src, dst, rng):
    data = bytearray(open(src, 'rb').read())
    for pos in rng.integers(8, len(data), 16):
        data[pos] ^= 0xFF
    open(dst, 'wb').write(bytes(data))


def _rewrite(convert):
    def mutate(src, dst, rng):
        cv2.imwrite(dst, convert(cv2.imread(src, cv2.IMREAD_COLOR)))
    return mutate


IMAGE_MUTATIONS: Dict[str, Callable] = {
    'img_truncated': _truncate,
    'img_random_bytes': _random_bytes,
    'img_flipped_bytes': _flip_bytes,
    'img_empty_file': lambda s, d, r: open(d, 'wb').close(),
    'img_grey': _rewrite(lambda im: cv2.cvtColor(im, cv2.COLOR_BGR2GRAY)),
    'img_16bit': _rewrite(lambda im: im.astype(np.uint16) * 257),
    'img_rgba': _rewrite(lambda im: cv2.cvtColor(im, cv2.COLOR_BGR2BGRA)),
    'img_1x1': _rewrite(lambda im: im[:1, :1]),
    'img_smaller_than_ann': _rewrite(lambda im: im[:40, :60]),
    'img_directory': lambda s, d, r: os.makedirs(d),
}
MUTATIONS = sorted(JSON_MUTATIONS) + sorted(IMAGE_MUTATIONS)

# -- one variant ------------------------------------------------------------


def make_variant(root: str, out_dir: str, name: str, num_images: int,
                 rng: np.random.Generator) -> Tuple[str, str]:
    """Write the mutated annotation file (and image) of one variant.

    Returns:
        tuple[str, str]: The annotation file and the mutated file (the
        annotation file itself for JSON mutations).
    """
    with open(osp.join(root, ANN)) as f:
        coco = json.load(f)
    keep = [im['id'] for im in coco['images'][:num_images]]
    coco['images'] = coco['images'][:num_images]
    coco['annotations'] = [
        a for a in coco['annotations'] if a['image_id'] in keep
    ]
    os.makedirs(out_dir, exist_ok=True)
    ann_file = osp.join(out_dir, 'train.json')
    mutated = ann_file
    if name in JSON_MUTATIONS:
        JSON_MUTATIONS[name](coco, rng)
    else:
        index = int(rng.integers(len(coco['images'])))
        image = coco['images'][index]
        src = osp.join(root, 'leftImg8bit', 'train', image['file_name'])
        mutated = osp.join(out_dir, f'mutated_{index}.png')
        IMAGE_MUTATIONS[name](src, mutated, rng)
        image['file_name'] = mutated  # absolute: os.path.join keeps it
    with open(ann_file, 'w') as f:
        if name == 'json_truncated':
            f.write(json.dumps(coco)[:100])
        else:
            json.dump(coco, f)
    return ann_file, mutated


def build(data_root: str, scale: Tuple[int, int]):
    """The demo model (train mode) and its dataset config at ``scale``."""
    init_default_scope('mmdet')
    cfg = Config.fromfile(DEMO)
    dataset = copy.deepcopy(cfg.train_dataloader.dataset.dataset)
    for t in dataset.pipeline:
        if t['type'] == 'Resize':
            t['scale'] = scale
    dataset.update(data_root=data_root,
                   data_prefix=dict(img='leftImg8bit/train/'))
    torch.manual_seed(0)
    model = MODELS.build(cfg.model)
    model.init_weights()  # the heads' own init (focal priors, zero-inits)
    return model.train(), dataset


def run_variant(model, dataset_cfg: dict, ann_file: str) -> str:
    """Dataset + pipeline + one forward/backward; ``'ok'`` or raise."""
    cfg = copy.deepcopy(dataset_cfg)
    cfg.ann_file = ann_file
    dataset = DATASETS.build(cfg)
    items = [dataset[i] for i in range(len(dataset))]
    if not items:
        return 'ok'  # everything filtered out: nothing to train on
    data = model.data_preprocessor(pseudo_collate(items), True)
    model.zero_grad()
    losses = model(**data, mode='loss')
    total, log_vars = model.parse_losses(losses)
    bad = [k for k, v in log_vars.items() if not torch.isfinite(v).all()]
    if bad:
        raise FloatingPointError(f'non-finite losses {bad}')
    total.backward()
    bad = [
        n for n, p in model.named_parameters()
        if p.grad is not None and not torch.isfinite(p.grad).all()
    ]
    if bad:
        raise FloatingPointError(f'non-finite gradients {bad[:3]}')
    return 'ok'


def raised_in_package(err: BaseException) -> bool:
    """Whether ``err`` was raised by the package's own code (its last frame
    lies in the ``cbnet_mmdet`` package directory; a checkout or virtual
    environment that merely has ``cbnet_mmdet`` in its path does not
    count)."""
    frames = traceback.extract_tb(err.__traceback__)
    return bool(frames) and osp.abspath(frames[-1].filename).startswith(
        PACKAGE_DIR)


def classify(err: BaseException, mutated: str, ann_file: str) -> str:
    """``'clear error'`` or ``'crash'`` (see the module docstring)."""
    text = str(err)
    names = mutated in text or ann_file in text
    clear = isinstance(err, CLEAR_TYPES) and raised_in_package(err) and names
    return 'clear error' if clear else 'crash'


def sweep(data_root: str, variants: int, seed: int, num_images: int,
          scale: Tuple[int, int], work: str,
          mutations: List[str] = None) -> dict:
    """Run ``variants`` random variants (mutations cycled, random details).

    Returns:
        dict: ``tried``, ``outcomes`` (Counter), ``per_mutation`` and
        ``crashes`` (mutation, variant, error).
    """
    mutations = mutations or MUTATIONS
    model, dataset_cfg = build(data_root, scale)
    rng = np.random.default_rng(seed)
    per_mutation: Dict[str, Counter] = defaultdict(Counter)
    crashes, outcomes = [], Counter()
    for i in range(variants):
        name = mutations[i % len(mutations)]
        out_dir = osp.join(work, f'{i:04d}_{name}')
        ann_file, mutated = make_variant(data_root, out_dir, name,
                                         num_images, rng)
        try:
            outcome = run_variant(model, dataset_cfg, ann_file)
        except Exception as err:  # noqa: B902  (the point of the sweep)
            outcome = classify(err, mutated, ann_file)
            if outcome == 'crash':
                crashes.append(dict(
                    mutation=name, variant=out_dir,
                    error=f'{type(err).__name__}: {err}'[:500],
                    where=traceback.format_exception(err)[-2][:300]))
        per_mutation[name][outcome] += 1
        outcomes[outcome] += 1
        shutil.rmtree(out_dir, ignore_errors=True)
    return dict(tried=variants, outcomes=dict(outcomes),
                per_mutation={k: dict(v) for k, v in per_mutation.items()},
                crashes=crashes)


def markdown(result: dict) -> str:
    rows = ['| mutation | tried | ok | clear error | crash |',
            '|---|---|---|---|---|']
    for name, c in sorted(result['per_mutation'].items()):
        rows.append(f'| {name} | {sum(c.values())} | {c.get("ok", 0)} | '
                    f'{c.get("clear error", 0)} | {c.get("crash", 0)} |')
    o = result['outcomes']
    rows.append(f'| **total** | {result["tried"]} | {o.get("ok", 0)} | '
                f'{o.get("clear error", 0)} | {o.get("crash", 0)} |')
    return '\n'.join(rows)


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--data-root', help='Cityscapes-like COCO dataset '
                        '(default: a tiny generated one)')
    parser.add_argument('--variants', type=int, default=300)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--images', type=int, default=2,
                        help='training images per variant')
    parser.add_argument('--scale', type=int, nargs=2, default=(128, 64),
                        help='Resize scale (w h) of the pipeline')
    parser.add_argument('--out', default='work_dirs/fuzz_inputs.json')
    return parser.parse_args()


def main():
    args = parse_args()
    with tempfile.TemporaryDirectory(prefix='cbnet_fuzz_') as tmp:
        root = args.data_root
        if root is None:
            from cbnet_mmdet.datasets.cityscapes_to_coco import convert
            from cbnet_mmdet.datasets.synthetic import \
                generate_cityscapes_like
            root = osp.join(tmp, 'data')
            generate_cityscapes_like(root, num_train=4, num_val=1,
                                     img_size=(128, 256), seed=args.seed,
                                     empty_every=3, crowd_every=2)
            convert(root)
        start = time.time()
        result = sweep(root, args.variants, args.seed, args.images,
                       tuple(args.scale), osp.join(tmp, 'variants'))
        result['seconds'] = round(time.time() - start, 1)
    print(markdown(result))
    print(f'\n{result["tried"]} inputs tried, '
          f'{result["outcomes"].get("crash", 0)} crashes, '
          f'{result["seconds"]} s')
    for crash in result['crashes']:
        print(f'- {crash["mutation"]}: {crash["error"]}')
    os.makedirs(osp.dirname(osp.abspath(args.out)), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(result, f, indent=1)


if __name__ == '__main__':
    main()
