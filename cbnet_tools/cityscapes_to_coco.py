"""Convert Cityscapes ``gtFine`` instance annotations to COCO JSON.

Writes ``{out_dir}/instancesonly_filtered_gtFine_{split}.json`` in the format
of MMDetection's ``tools/dataset_converters/cityscapes.py`` (which its
``CityscapesDataset`` and ``CocoMetric`` read):

* ``images``: ``file_name`` (``'{city}/{stem}_leftImg8bit.png'``, relative
  to ``leftImg8bit/{split}/``), ``height``, ``width``, ``segm_file``
  (``'{city}/{stem}_gtFine_labelIds.png'``), ``id`` (1, 2, ...).
* ``annotations``: one per instance id of ``*_gtFine_instanceIds.png``
  whose label has instances and is evaluated: ``iscrowd`` (1 for group
  regions, whose id is the bare label id < 1000), ``category_id`` (the
  cityscapesscripts label id), ``bbox`` (COCO ``[x, y, w, h]``, pixels),
  ``area`` (pixels), ``segmentation`` (COCO RLE), ``image_id``, ``id``
  (1, 2, ... over the split).
* ``categories``: the 8 evaluated instance labels of
  ``cityscapesscripts.helpers.labels`` with their ids (24..33).

Three deliberate differences from MMDetection's script: ids start at 1
(pycocotools' ``COCOeval`` stores the id of the matched annotation and reads
0 as "no match", so MMDet's annotation id 0 is never a true positive), images
are sorted (its ``glob`` order depends on the file system) and an
annotation-free split keeps an empty ``annotations`` list instead of dropping
the key. Malformed
input raises ``FileNotFoundError`` / ``ValueError`` naming the file.
"""
import glob
import os
import os.path as osp
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import pycocotools.mask as mask_utils
from cityscapesscripts.helpers.labels import labels
from mmengine.fileio import dump
from mmengine.utils import track_parallel_progress, track_progress
from PIL import Image

#: The evaluated Cityscapes instance labels (person ... bicycle).
EVAL_LABELS = tuple(
    lab for lab in labels if lab.hasInstances and not lab.ignoreInEval)
#: Label ids of :data:`EVAL_LABELS` (24, 25, 26, 27, 28, 31, 32, 33).
EVAL_LABEL_IDS = np.array([lab.id for lab in EVAL_LABELS])
#: MMDetection's output names, per split.
JSON_NAME = 'instancesonly_filtered_gtFine_{}.json'
IMG_SUFFIX = '_leftImg8bit.png'
#: Masks RLE-encoded per call, bounding memory at H * W * MASK_CHUNK bytes
#: (32 MiB at 1024x2048).
MASK_CHUNK = 16

FileTriple = Tuple[str, str, str]


def read_png(path: str, mode: Optional[str] = None) -> np.ndarray:
    """Read a PNG fully, naming the file in any error.

    Args:
        path (str): PNG file.
        mode (str, optional): PIL mode to convert to.

    Returns:
        np.ndarray: The pixels (``uint16[H, W]`` for Cityscapes
        ``instanceIds``).
    """
    if not osp.isfile(path):
        raise FileNotFoundError(f'missing file: {path}')
    try:
        with Image.open(path) as img:
            img.load()
            if mode is not None:
                img = img.convert(mode)
            return np.asarray(img)
    except (OSError, SyntaxError, ValueError) as err:
        raise ValueError(f'cannot read image {path}: {err}') from err


def collect_files(root: str,
                  split: str,
                  img_dir: str = 'leftImg8bit',
                  gt_dir: str = 'gtFine') -> List[FileTriple]:
    """Images of a split with their instance and label id files.

    Args:
        root (str): Cityscapes root (holding ``leftImg8bit`` and
            ``gtFine``).
        split (str): ``'train'``, ``'val'`` or ``'test'``.
        img_dir (str): Image folder name under ``root``.
        gt_dir (str): Annotation folder name under ``root``.

    Returns:
        list[tuple[str, str, str]]: Sorted ``(image, instanceIds,
        labelIds)`` paths.

    Raises:
        FileNotFoundError: A folder is missing or empty, or an image has
            no annotation files (the message names them).
    """
    split_img = osp.join(root, img_dir, split)
    split_gt = osp.join(root, gt_dir, split)
    for folder in (split_img, split_gt):
        if not osp.isdir(folder):
            raise FileNotFoundError(f'missing Cityscapes folder: {folder}')
    images = sorted(glob.glob(osp.join(split_img, '*', '*' + IMG_SUFFIX)))
    if not images:
        raise FileNotFoundError(
            f'no {{city}}/*{IMG_SUFFIX} images in {split_img}')
    files = []
    for img in images:
        city_stem = osp.relpath(img, split_img)[:-len(IMG_SUFFIX)]
        gt = osp.join(split_gt, city_stem + '_gtFine_')
        triple = (img, gt + 'instanceIds.png', gt + 'labelIds.png')
        for ann in triple[1:]:
            if not osp.isfile(ann):
                raise FileNotFoundError(
                    f'image {img} has no annotation file {ann}')
        files.append(triple)
    return files


def image_annotations(files: FileTriple) -> dict:
    """COCO image entry and annotations of one image.

    All instance masks of the image are RLE-encoded together
    (``MASK_CHUNK`` at a time), as are their areas and boxes.

    Args:
        files (tuple[str, str, str]): ``(image, instanceIds, labelIds)``.

    Returns:
        dict: ``file_name``, ``height``, ``width``, ``segm_file`` and
        ``anno_info`` (annotations without ids).
    """
    img_file, inst_file, segm_file = files
    inst = read_png(inst_file)
    if inst.ndim != 2:
        raise ValueError(f'{inst_file}: expected a single-channel id image, '
                         f'got shape {inst.shape}')
    try:  # the header is enough to check the image is a PNG of that size
        with Image.open(img_file) as img:
            size = img.size
    except (OSError, SyntaxError, ValueError) as err:
        raise ValueError(f'cannot read image {img_file}: {err}') from err
    if size != (inst.shape[1], inst.shape[0]):
        raise ValueError(f'{img_file} is {size[0]}x{size[1]} but '
                         f'{inst_file} is {inst.shape[1]}x{inst.shape[0]}')
    ids = np.unique(inst)
    label_ids = np.where(ids >= 1000, ids // 1000, ids)
    keep = np.isin(label_ids, EVAL_LABEL_IDS)
    ids, label_ids = ids[keep], label_ids[keep]
    rles = []
    for start in range(0, len(ids), MASK_CHUNK):
        masks = inst[..., None] == ids[None, None, start:start + MASK_CHUNK]
        rles += mask_utils.encode(np.asfortranarray(masks, dtype=np.uint8))
    areas = mask_utils.area(rles) if rles else []
    boxes = mask_utils.toBbox(rles) if rles else []
    anno_info = []
    for inst_id, label_id, rle, area, box in zip(ids, label_ids, rles,
                                                 areas, boxes):
        rle['counts'] = rle['counts'].decode()
        anno_info.append(
            dict(
                iscrowd=int(inst_id < 1000),
                category_id=int(label_id),
                bbox=box.tolist(),
                area=int(area),
                segmentation=rle))
    city = osp.basename(osp.dirname(img_file))
    return dict(
        file_name=osp.join(city, osp.basename(img_file)),
        height=int(inst.shape[0]),
        width=int(inst.shape[1]),
        anno_info=anno_info,
        segm_file=osp.join(city, osp.basename(segm_file)))


#: First image and annotation id. Not 0: ``COCOeval.evaluateImg`` records
#: a match as the matched id and tests it for truth, so a detection matched
#: to annotation 0 counts as a false positive.
FIRST_ID = 1


def to_coco(image_infos: Sequence[dict]) -> dict:
    """Number images and annotations from :data:`FIRST_ID` and add the
    categories."""
    out = dict(images=[], annotations=[], categories=[])
    for img_id, info in enumerate(image_infos, start=FIRST_ID):
        info = dict(info)
        annos = info.pop('anno_info')
        info['id'] = img_id
        out['images'].append(info)
        for anno in annos:
            out['annotations'].append(
                dict(anno, image_id=img_id,
                     id=FIRST_ID + len(out['annotations'])))
    out['categories'] = [
        dict(id=lab.id, name=lab.name) for lab in EVAL_LABELS
    ]
    return out


def convert(cityscapes_root: str,
            out_dir: Optional[str] = None,
            splits: Sequence[str] = ('train', 'val'),
            nproc: int = 1,
            img_dir: str = 'leftImg8bit',
            gt_dir: str = 'gtFine') -> Dict[str, str]:
    """Convert splits of a Cityscapes tree to MMDetection's COCO JSON.

    Args:
        cityscapes_root (str): Root holding ``leftImg8bit`` and ``gtFine``.
        out_dir (str, optional): Output folder; default
            ``{cityscapes_root}/annotations`` (where MMDet's configs look).
        splits (Sequence[str]): Splits to convert.
        nproc (int): Worker processes.
        img_dir (str): Image folder name.
        gt_dir (str): Annotation folder name.

    Returns:
        dict[str, str]: Written JSON path per split.
    """
    if not osp.isdir(cityscapes_root):
        raise FileNotFoundError(
            f'missing Cityscapes root folder: {cityscapes_root}')
    out_dir = out_dir or osp.join(cityscapes_root, 'annotations')
    os.makedirs(out_dir, exist_ok=True)
    written = {}
    for split in splits:
        files = collect_files(cityscapes_root, split, img_dir, gt_dir)
        print(f'Converting {len(files)} {split} images of {cityscapes_root}')
        if nproc > 1:
            infos = track_parallel_progress(image_annotations, files, nproc)
        else:
            infos = track_progress(image_annotations, files)
        written[split] = osp.join(out_dir, JSON_NAME.format(split))
        dump(to_coco(infos), written[split])
    return written
