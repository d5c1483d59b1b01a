"""Statistics of a COCO instance annotation file (the converter's output).

What decides how hard a detection set is: instances per image, the class
mix and the size distribution. Sizes are given three ways, all as
fractions of the non-crowd instances:

* COCO's area ranges (``small`` < 32^2 px, ``medium`` < 96^2,
  ``large``), those of ``COCOeval`` (APs / APm / APl);
* finer absolute bins (:data:`AREA_BINS`, pixels);
* the relative size ``sqrt(area / image area)`` (:data:`REL_BINS`), which
  compares sets of different resolutions (128x256 generated images with
  1024x2048 Cityscapes).

Crowd regions (``iscrowd = 1``) are counted apart and left out of the
rest, as ``COCOeval`` ignores them.
"""
import json
import os.path as osp
from typing import Dict, Sequence

import numpy as np

from .markdown import markdown_table

#: COCOeval's area ranges, pixels (``areaRng``: small, medium, large).
COCO_AREAS = (('small', 0, 32**2), ('medium', 32**2, 96**2),
              ('large', 96**2, float('inf')))
#: Absolute area bins, pixels (edges: side lengths of square objects).
AREA_BINS = (0, 8, 16, 32, 64, 96, 128, 256, float('inf'))
#: Relative size bins, ``sqrt(area / (H W))``.
REL_BINS = (0, 0.01, 0.02, 0.05, 0.1, 0.2, float('inf'))


def load_coco(path: str) -> dict:
    """Read and check a COCO instance JSON.

    Raises:
        FileNotFoundError: No such file.
        ValueError: Not JSON, a missing key, an annotation of an unknown
            image or category, a missing or negative area (the message
            names the file and the annotation id).
    """
    if not osp.isfile(path):
        raise FileNotFoundError(f'missing annotation file: {path}')
    try:
        with open(path) as f:
            coco = json.load(f)
    except json.JSONDecodeError as err:
        raise ValueError(f'{path} is not valid JSON: {err}') from err
    for key in ('images', 'annotations', 'categories'):
        if not isinstance(coco.get(key), list):
            raise ValueError(f'{path}: no "{key}" list')
    img_ids = {img['id'] for img in coco['images']}
    cat_ids = {cat['id'] for cat in coco['categories']}
    for ann in coco['annotations']:
        where = f'{path}: annotation {ann.get("id")}'
        if ann.get('image_id') not in img_ids:
            raise ValueError(f'{where} refers to image {ann.get("image_id")}'
                             ' that is not in "images"')
        if ann.get('category_id') not in cat_ids:
            raise ValueError(f'{where} has unknown category '
                             f'{ann.get("category_id")}')
        area = ann.get('area')
        if not isinstance(area, (int, float)) or area < 0:
            raise ValueError(f'{where} has no valid "area": {area!r}')
    return coco


def _fractions(values: np.ndarray, edges: Sequence[float],
               fmt: str) -> Dict[str, float]:
    """Share of ``values`` in each ``[lo, hi)`` bin, keyed
    ``fmt.format(lo, hi)`` (``inf`` for the open end)."""
    out = {}
    n = max(len(values), 1)
    for lo, hi in zip(edges[:-1], edges[1:]):
        key = fmt.format(f'{lo:g}', f'{hi:g}').replace('inf^2', 'inf')
        out[key] = float(((values >= lo) & (values < hi)).sum() / n)
    return out


def coco_statistics(coco: dict) -> dict:
    """Statistics of a COCO instance dict (see the module docstring).

    Returns:
        dict: ``images``, ``images_with_instances``, ``instances``
        (non-crowd), ``crowd``; ``per_image`` (mean, median, std, min, max
        of non-crowd instances per image); ``per_class`` (count) and
        ``per_class_fraction``; ``coco_area``, ``area_hist`` and
        ``rel_size_hist`` (fractions of the non-crowd instances).
    """
    images = {img['id']: img for img in coco['images']}
    names = {cat['id']: cat['name'] for cat in coco['categories']}
    anns = [a for a in coco['annotations'] if not a.get('iscrowd', 0)]
    per_img = {i: 0 for i in images}
    per_class = {name: 0 for name in names.values()}
    areas, rel = [], []
    for a in anns:
        per_img[a['image_id']] += 1
        per_class[names[a['category_id']]] += 1
        img = images[a['image_id']]
        areas.append(float(a['area']))
        rel.append(np.sqrt(a['area'] / (img['height'] * img['width'])))
    counts = np.array(list(per_img.values()), float)
    areas, rel = np.array(areas), np.array(rel)
    n = max(len(anns), 1)
    return dict(
        images=len(images),
        images_with_instances=int((counts > 0).sum()),
        instances=len(anns),
        crowd=len(coco['annotations']) - len(anns),
        per_image=dict(
            mean=float(counts.mean()) if len(counts) else 0.0,
            median=float(np.median(counts)) if len(counts) else 0.0,
            std=float(counts.std()) if len(counts) else 0.0,
            min=int(counts.min()) if len(counts) else 0,
            max=int(counts.max()) if len(counts) else 0),
        per_class=per_class,
        per_class_fraction={k: v / n for k, v in per_class.items()},
        coco_area={
            name: float(((areas >= lo) & (areas < hi)).sum() / n)
            for name, lo, hi in COCO_AREAS
        },
        area_hist=_fractions(np.sqrt(areas), AREA_BINS, '[{}^2, {}^2)'),
        rel_size_hist=_fractions(rel, REL_BINS, '[{}, {})'))


def format_statistics(stats: dict, title: str) -> str:
    """Markdown tables of :func:`coco_statistics`."""
    pi = stats['per_image']
    lines = [
        f'## {title}', '',
        f'{stats["images"]} images ({stats["images_with_instances"]} with '
        f'instances), {stats["instances"]} instances, {stats["crowd"]} crowd '
        'regions', '',
        f'instances per image: mean {pi["mean"]:.2f}, median '
        f'{pi["median"]:g}, std {pi["std"]:.2f}, min {pi["min"]}, max '
        f'{pi["max"]}', ''
    ] + markdown_table(
        ['class', 'instances', 'fraction'],
        [[name, count, f'{stats["per_class_fraction"][name]:.3f}']
         for name, count in stats['per_class'].items()], align='lrr')
    for key, head in (('coco_area', 'COCO area range'),
                      ('area_hist', 'area (px)'),
                      ('rel_size_hist', 'sqrt(area / image area)')):
        lines += [''] + markdown_table(
            [head, 'fraction'],
            [[k, f'{v:.3f}'] for k, v in stats[key].items()], align='lr')
    return '\n'.join(lines) + '\n'
