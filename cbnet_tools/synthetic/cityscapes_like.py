"""Generate a small dataset in the exact Cityscapes / Foggy Cityscapes layout.

Written under ``out_root``::

    leftImg8bit/{split}/{city}/{stem}_leftImg8bit.png          RGB, uint8
    gtFine/{split}/{city}/{stem}_gtFine_polygons.json          polygons
    gtFine/{split}/{city}/{stem}_gtFine_labelIds.png           uint8
    gtFine/{split}/{city}/{stem}_gtFine_instanceIds.png        16 bit
    depth/{split}/{city}/{stem}_depth.png                      16 bit, cm
    leftImg8bit_foggy/{split}/{city}/
        {stem}_leftImg8bit_foggy_beta_{0.005,0.01,0.02}.png    RGB, uint8
    generator_record.json                                      what was drawn

The label and instance images are rendered from the polygons by
cityscapesscripts' own ``createLabelImage`` / ``createInstanceImage``, so
their encodings are the released ones: ``labelIds`` per
``cityscapesscripts.helpers.labels``, ``instanceIds = labelId * 1000 + k``
for instances and ``labelId`` for crowd (``*group``) and stuff regions.

The scenes (:mod:`.scene`) are streets seen from a car: textured road,
sidewalks, facades and trees (:mod:`.texture`), rows of parked cars,
traffic, pedestrians, riders on bicycles and motorcycles, drawn far to
near so that nearer objects hide farther ones: the instance image holds
each instance's visible part, as Cityscapes annotates it.

The depth PNG stores, in centimetres, the depth along the optical axis of
the surface SEEN at each pixel (uint16, 65535 = 655.35 m; sky = 600 m;
through a bicycle's wheels, what is behind it). The foggy images apply the
atmospheric scattering model used to build Foggy Cityscapes (Sakaridis et
al., 2018; :mod:`cbnet_mmdet.utils.scattering`, the model ``CBNetAddFog``
applies too) to that stored depth: ``I = R t + L (1 - t)``,
``t = exp(-beta d)`` with ``R`` the clear image and ``L`` the atmospheric
light in [0, 1], ``d`` in metres and ``beta`` in 1/m (visibility
2.996 / beta: 150 m at 0.02).

Everything is a function of ``seed`` (each image has its own random stream
from ``(seed, split, index)``): the same call writes byte-identical files.
"""
import json
import os
import os.path as osp
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
from cityscapesscripts.helpers.annotation import Annotation
from cityscapesscripts.helpers.labels import id2label, name2label
from cityscapesscripts.preparation.json2instanceImg import createInstanceImage
from cityscapesscripts.preparation.json2labelImg import createLabelImage
from mmengine.utils import track_parallel_progress, track_progress
from PIL import Image, ImageChops, ImageDraw

from cbnet_mmdet.datasets.cityscapes_paths import FOGGY_BETAS, foggy_path
from cbnet_mmdet.utils.scattering import (ATMOSPHERIC_LIGHT, scatter,
                                          transmission)
from .scene import (INSTANCE_CLASSES, MIN_HEIGHT_PX, SceneCamera, ScenePolygon,
                    pixel_depth, sample_scene)
from .texture import render_rgb

#: Cities of each split (real Cityscapes city names).
CITIES = {'train': ('aachen', 'bochum'), 'val': ('frankfurt', 'lindau')}
#: Depth PNG scale: stored value = metres * DEPTH_SCALE.
DEPTH_SCALE = 100.0
#: Scenes are redrawn (up to MAX_TRIES times) until each of the 8 classes
#: (and the crowd region, if any) has an instance at least MIN_VISIBLE_PX
#: pixels visible (occlusions may hide one entirely).
MAX_TRIES, MIN_VISIBLE_PX = 50, 4
#: Record of what was drawn, written at ``out_root``.
RECORD_FILE = 'generator_record.json'


def image_stem(split: str, index: int) -> Tuple[str, str]:
    """``(city, stem)`` of image ``index`` of ``split``, e.g.
    ``('frankfurt', 'frankfurt_000001_000019')``."""
    cities = CITIES[split]
    city = cities[index % len(cities)]
    # 000019 is the annotated frame of every Cityscapes sequence
    return city, f'{city}_{index:06d}_000019'


def render_depth(depth_m: np.ndarray) -> np.ndarray:
    """The depth PNG content: ``float[H, W]`` metres to ``uint16[H, W]``
    centimetres (rounded, saturating at 655.35 m)."""
    return np.clip(np.rint(depth_m * DEPTH_SCALE), 0,
                   np.iinfo(np.uint16).max).astype(np.uint16)


def add_fog(rgb: np.ndarray, depth_m: np.ndarray, beta: float,
            light: Sequence[float] = ATMOSPHERIC_LIGHT) -> np.ndarray:
    """Atmospheric scattering model ``I = R t + L (1 - t)``,
    ``t = exp(-beta d)`` (:mod:`cbnet_mmdet.utils.scattering`), on the
    [0, 1] scale, then rounded to 8 bits.

    Args:
        rgb (np.ndarray): ``uint8[H, W, 3]`` clear image ``R``.
        depth_m (np.ndarray): ``float[H, W]`` distance ``d``, metres.
        beta (float): Attenuation coefficient, 1/m.
        light (Sequence[float]): Atmospheric light ``L``, RGB in [0, 1].

    Returns:
        np.ndarray: ``uint8[H, W, 3]`` foggy image.
    """
    t = transmission(depth_m, beta)[..., None]
    foggy = scatter(rgb / 255.0, t, np.asarray(light, np.float64))
    return np.clip(np.rint(foggy * 255), 0, 255).astype(np.uint8)


def _polygons_json(scene: Sequence[ScenePolygon], cam: SceneCamera) -> dict:
    """The ``*_gtFine_polygons.json`` content (the released keys)."""
    return dict(
        imgHeight=cam.height,
        imgWidth=cam.width,
        objects=[
            dict(label=p.label, polygon=p.polygon.tolist()) for p in scene
        ])


def _rasterise(polys: dict, scene: Sequence[ScenePolygon]
               ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rasterise a polygons JSON.

    Returns:
        tuple: ``uint8[H, W]`` label ids and ``int32[H, W]`` instance ids
        (cityscapesscripts' renderers), and ``int32[H, W]`` index of the
        polygon SEEN at each pixel (same painter's order, with the painted
        ``look`` of see-through objects; for colours and depth).
    """
    ann = Annotation()
    ann.fromJsonText(json.dumps(polys))
    label_ids = np.asarray(createLabelImage(ann, 'ids'), np.uint8)
    inst_ids = np.asarray(createInstanceImage(ann, 'ids'), np.int32)
    size = (polys['imgWidth'], polys['imgHeight'])
    order = Image.new('I', size, 0)
    draw = ImageDraw.Draw(order)
    for i, p in enumerate(scene):
        if p.look is None:
            draw.polygon([tuple(v) for v in p.polygon.tolist()], fill=i)
        else:  # the painted parts, inside the annotated outline
            seen = Image.new('1', size, 0)
            ImageDraw.Draw(seen).polygon(
                [tuple(v) for v in p.look.tolist()], fill=1)
            outline = Image.new('1', size, 0)
            ImageDraw.Draw(outline).polygon(
                [tuple(v) for v in p.polygon.tolist()], fill=1)
            order.paste(i, mask=ImageChops.logical_and(seen, outline))
    return label_ids, inst_ids, np.asarray(order, np.int32)


def _all_classes_visible(scene: Sequence[ScenePolygon], cam: SceneCamera,
                         crowd: bool) -> bool:
    """Whether each of the 8 classes (and a crowd region if ``crowd``)
    keeps at least :data:`MIN_VISIBLE_PX` visible pixels (a quick
    painter's-order raster of the annotated polygons: what cityscapesscripts
    will draw)."""
    order = Image.new('I', (cam.width, cam.height), 0)
    draw = ImageDraw.Draw(order)
    for i, p in enumerate(scene):
        draw.polygon([tuple(v) for v in p.polygon.tolist()], fill=i)
    visible = np.bincount(np.asarray(order, np.int32).ravel(),
                          minlength=len(scene))
    seen = {p.label for p, n in zip(scene, visible) if n >= MIN_VISIBLE_PX}
    return seen >= set(INSTANCE_CLASSES) and (
        not crowd or any(label.endswith('group') for label in seen))


def _instances(inst_ids: np.ndarray) -> List[dict]:
    """What the instance image holds for the 8 classes: one entry per id
    with its label, crowd flag and visible area in pixels."""
    counts = np.bincount(inst_ids.ravel())
    ids = np.flatnonzero(counts)
    areas = counts[ids]
    label_ids = np.where(ids >= 1000, ids // 1000, ids)
    keep = np.isin(label_ids,
                   [name2label[c].id for c in INSTANCE_CLASSES])
    return [
        dict(instance_id=int(i), label=id2label[int(lab)].name,
             label_id=int(lab), iscrowd=int(i < 1000), area=int(a))
        for i, lab, a in zip(ids[keep], label_ids[keep], areas[keep])
    ]


def _save(arr: np.ndarray, path: str) -> None:
    os.makedirs(osp.dirname(path), exist_ok=True)
    # fast zlib level: noisy images barely compress better at the default 6
    Image.fromarray(arr).save(path, compress_level=1)


def generate_image(out_root: str, split: str, index: int,
                   img_size: Tuple[int, int], seed: int,
                   betas: Sequence[float], empty: bool,
                   crowd: bool, density: float = 1.0,
                   min_height_px: float = MIN_HEIGHT_PX) -> dict:
    """Generate and write one image with all its files.

    Args:
        out_root (str): Dataset root.
        split (str): ``'train'`` or ``'val'``.
        index (int): Image index within the split.
        img_size (tuple[int, int]): ``(height, width)``, pixels.
        seed (int): Dataset seed.
        betas (Sequence[float]): Fog densities to write, 1/m.
        empty (bool): Draw no instances.
        crowd (bool): Add a crowd region.
        density (float): Scale of the object counts (see
            :func:`~.scene.sample_scene`).
        min_height_px (float): Height of the smallest object drawn, pixels.

    Returns:
        dict: Record ``{split, city, stem, height, width, instances}`` with
        ``instances`` as in :func:`_instances`.
    """
    split_code = tuple(CITIES).index(split)
    rng = np.random.default_rng(np.random.SeedSequence(
        [seed, split_code, index]))
    cam = SceneCamera(*img_size)
    for _ in range(MAX_TRIES):
        scene = sample_scene(cam, rng, empty=empty, crowd=crowd,
                             density=density, min_height_px=min_height_px)
        if empty or _all_classes_visible(scene, cam, crowd):
            break
    else:
        raise RuntimeError(
            f'could not draw all 8 classes visibly in {MAX_TRIES} tries '
            f'at {img_size}: use a larger image size')
    polys = _polygons_json(scene, cam)
    label_ids, inst_ids, order = _rasterise(polys, scene)
    depth_m = pixel_depth(order, scene, cam)
    depth = render_depth(depth_m)
    rgb = render_rgb(order, scene, cam, depth_m, rng)

    city, stem = image_stem(split, index)
    gt = osp.join(out_root, 'gtFine', split, city, stem + '_gtFine_')
    img_path = osp.join(out_root, 'leftImg8bit', split, city,
                        stem + '_leftImg8bit.png')
    _save(rgb, img_path)
    _save(label_ids, gt + 'labelIds.png')
    # 16-bit like the released files (ids reach 33999)
    _save(inst_ids.astype(np.uint16), gt + 'instanceIds.png')
    with open(gt + 'polygons.json', 'w') as f:
        json.dump(polys, f, indent=1)
    _save(depth, osp.join(out_root, 'depth', split, city, stem + '_depth.png'))
    for beta in betas:
        _save(add_fog(rgb, depth / DEPTH_SCALE, beta),
              foggy_path(img_path, beta))
    return dict(split=split, city=city, stem=stem, height=cam.height,
                width=cam.width, instances=_instances(inst_ids))


def _generate_job(job: tuple) -> dict:
    return generate_image(*job)


def generate_cityscapes_like(out_root: str,
                             num_train: int = 40,
                             num_val: int = 10,
                             img_size: Tuple[int, int] = (256, 512),
                             seed: int = 0,
                             betas: Sequence[float] = FOGGY_BETAS,
                             empty_every: int = 5,
                             crowd_every: int = 2,
                             nproc: int = 1,
                             density: float = 1.0,
                             min_height_px: float = MIN_HEIGHT_PX
                             ) -> Dict[str, list]:
    """Write a deterministic Cityscapes-like dataset (train and val).

    Args:
        out_root (str): Dataset root, created if missing.
        num_train (int): Training images.
        num_val (int): Validation images.
        img_size (tuple[int, int]): ``(height, width)`` in pixels; the
            default 256x512 keeps the demo trainable on a CPU.
        seed (int): Seed; equal seeds give byte-identical files.
        betas (Sequence[float]): Fog attenuation coefficients, 1/m, each
            one of :data:`FOGGY_BETAS`.
        empty_every (int): Every ``empty_every``-th image of a split
            (index ``empty_every - 1``, ``2 * empty_every - 1``...) has no
            instances; 0 for none.
        crowd_every (int): Every ``crowd_every``-th non-empty image (from
            index 0) has a crowd region; 0 for none.
        nproc (int): Worker processes.
        density (float): Scale of the mean object counts per image (1:
            about 19 instances, see docs/dataset.md).
        min_height_px (float): Objects shorter than this (pixels, standing
            height) are not drawn: 8 keeps objects a small CPU-trained
            detector can learn at 128x256; at 1024x2048 it drops nothing.

    Returns:
        dict[str, list]: Per split, the records of :func:`generate_image`
        (also written to ``out_root/generator_record.json``).
    """
    for beta in betas:
        if beta not in FOGGY_BETAS:
            raise ValueError(f'beta {beta} is not one of {FOGGY_BETAS}')
    h, w = img_size
    if h < 32 or w < 32:
        raise ValueError(f'img_size must be at least 32x32, got {img_size}')
    if density <= 0:
        raise ValueError(f'density must be > 0, got {density}')
    jobs = []
    for split, num in (('train', num_train), ('val', num_val)):
        for i in range(num):
            empty = empty_every > 0 and (i + 1) % empty_every == 0
            crowd = (not empty and crowd_every > 0 and i % crowd_every == 0)
            jobs.append((out_root, split, i, (h, w), seed, tuple(betas),
                         empty, crowd, density, min_height_px))
    if nproc > 1:
        records = track_parallel_progress(_generate_job, jobs, nproc)
    else:
        records = track_progress(_generate_job, jobs)
    out = {'train': [], 'val': []}
    for rec in records:
        out[rec['split']].append(rec)
    meta = dict(seed=seed, img_size=[h, w], betas=list(betas),
                density=density, min_height_px=min_height_px,
                depth_unit_m=1 / DEPTH_SCALE,
                atmospheric_light=list(ATMOSPHERIC_LIGHT), splits=out)
    with open(osp.join(out_root, RECORD_FILE), 'w') as f:
        json.dump(meta, f, indent=1)
    return out


def record_differences(record: dict, num_train: int, num_val: int,
                       img_size: Tuple[int, int], seed: int,
                       betas: Sequence[float], density: float,
                       min_height_px: float) -> List[str]:
    """What a generator record says that the arguments of
    :func:`generate_cityscapes_like` would not make (empty: the same
    dataset), e.g. ``['num_train: 32 there, 200 asked']``."""
    there = dict(
        num_train=len(record['splits']['train']),
        num_val=len(record['splits']['val']),
        img_size=list(record['img_size']), seed=record['seed'],
        betas=list(record['betas']), density=record['density'],
        min_height_px=record['min_height_px'])
    asked = dict(num_train=num_train, num_val=num_val,
                 img_size=list(img_size), seed=seed, betas=list(betas),
                 density=density, min_height_px=min_height_px)
    return [f'{k}: {there[k]} there, {asked[k]} asked' for k in asked
            if there[k] != asked[k]]


def load_record(out_root: str) -> Optional[dict]:
    """The record written by :func:`generate_cityscapes_like`, or None."""
    path = osp.join(out_root, RECORD_FILE)
    if not osp.isfile(path):
        return None
    with open(path) as f:
        return json.load(f)


def tiny_converted(out_root: str) -> str:
    """A tiny generated dataset with its COCO annotations: 4 train and 3
    val images at 128x256 (the test suite's size), for dry runs of the
    sets that train on generated scenes (``tools/device/run_all.py``).

    Returns:
        str: ``out_root``.
    """
    from cbnet_tools.cityscapes_to_coco import convert
    generate_cityscapes_like(out_root, num_train=4, num_val=3,
                             img_size=(128, 256), seed=0, empty_every=3,
                             crowd_every=2)
    convert(out_root)
    return out_root
