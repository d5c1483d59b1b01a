"""A stream of real frames from several labelled sets, for the offload table.

The offload evaluation (:mod:`.offload`) scores route.py's answers on a
folder of frames against one COCO instances file. Real frames come from
sets in different formats (DAWN's fog as a VOC folder with boxes, COCO
street photos as COCO instances) and stand for different conditions (real
fog, clear). :func:`build_stream` lays them out as one folder,
``{condition}/{file name}`` (links to the photos, nothing copied), with
one COCO instances file whose ``file_name`` is that relative path and
whose categories are the project's classes, so that a frame's condition is
the folder it sits in (``offload_curve(..., conditions='folder')``).

A VOC folder contributes the seeded val split the real-fog configs test on
(:class:`cbnet_mmdet.datasets.CBNetVOCFogDataset`, ``split='val'``, 30 %,
seed 0), read by that class, so every name check and box check of the
training data applies; a COCO file contributes the images it lists with
the annotations of the project's classes (others dropped, counted).
"""
import glob
import json
import os
import os.path as osp
from typing import Dict, List, Sequence, Tuple

from cbnet_mmdet.datasets.voc_fog import CITYSCAPES_CLASSES

#: Category ids of the stream's file: the project's classes from 1.
CATEGORIES = [dict(id=i, name=c) for i, c in enumerate(CITYSCAPES_CLASSES,
                                                       1)]


#: The image files a folder of frames is read for (route.py,
#: load_test.py): extension -> the content type load_test.py sends them as.
IMAGE_TYPES = {'.png': 'image/png', '.jpg': 'image/jpeg',
               '.jpeg': 'image/jpeg', '.bmp': 'image/bmp'}
IMAGE_EXTS = tuple(IMAGE_TYPES)


def list_images(folder: str) -> List[str]:
    """Paths of the images under ``folder``, searched recursively, sorted.

    The one listing of a stream folder's frames: route.py answers them in
    this order and load_test.py sends them in it, so that the frame order
    of a routed run and a load test of the same folder agree.

    Raises:
        FileNotFoundError: No image (:data:`IMAGE_EXTS`) under ``folder``.
    """
    files = sorted(
        f for f in glob.glob(osp.join(folder, '**', '*'), recursive=True)
        if osp.splitext(f)[1].lower() in IMAGE_EXTS and osp.isfile(f))
    if not files:
        raise FileNotFoundError(
            f'no images ({", ".join(IMAGE_EXTS)}) under {folder}')
    return files


def _check_condition(name: str) -> str:
    if not name or '/' in name or name.startswith('.'):
        raise ValueError(f'condition {name!r}: a folder name is expected '
                         '(e.g. fog, clear)')
    return name


def voc_frames(root: str, split: str = 'val', val_fraction: float = 0.3,
               split_seed: int = 0, img_suffix: str = '.jpg'
               ) -> List[Tuple[str, int, int, List[Dict]]]:
    """(image path, width, height, objects) of a VOC folder's seeded split;
    an object is ``{'name', 'bbox': [x, y, w, h], 'iscrowd'}`` (VOC's
    difficult objects as crowd, which COCO ignores)."""
    from cbnet_mmdet.datasets.voc_fog import CBNetVOCFogDataset
    ds = CBNetVOCFogDataset(data_root=root, ann_file='', split=split,
                            val_fraction=val_fraction,
                            split_seed=split_seed, img_suffix=img_suffix,
                            test_mode=True, lazy_init=True)
    classes = ds.metainfo['classes']
    out = []
    for info in ds.load_data_list():
        objs = []
        for inst in info['instances']:
            x1, y1, x2, y2 = inst['bbox']
            objs.append(dict(name=classes[inst['bbox_label']],
                             bbox=[x1, y1, x2 - x1, y2 - y1],
                             iscrowd=int(inst.get('ignore_flag', 0))))
        out.append((info['img_path'], info['width'], info['height'], objs))
    return out


def coco_frames(ann_file: str, img_dir: str
                ) -> Tuple[List[Tuple[str, int, int, List[Dict]]], int]:
    """(image path, width, height, objects) of every image of a COCO
    instances file, and how many annotations were dropped (classes that
    are not the project's)."""
    with open(ann_file) as f:
        coco = json.load(f)
    for key in ('images', 'annotations', 'categories'):
        if key not in coco:
            raise ValueError(f'{ann_file}: no {key!r} (a COCO instances '
                             'file is expected)')
    names = {c['id']: c['name'] for c in coco['categories']}
    per: Dict[int, List[Dict]] = {img['id']: [] for img in coco['images']}
    dropped = 0
    for a in coco['annotations']:
        name = names.get(a['category_id'])
        if a['image_id'] not in per:
            raise ValueError(f"{ann_file}: annotation {a.get('id')} of "
                             f"image {a['image_id']}, which is not listed")
        if name not in CITYSCAPES_CLASSES:
            dropped += 1
            continue
        per[a['image_id']].append(dict(name=name, bbox=list(a['bbox']),
                                       iscrowd=int(a.get('iscrowd', 0))))
    out = []
    for img in coco['images']:
        path = osp.join(img_dir, img['file_name'])
        if not osp.isfile(path):
            raise FileNotFoundError(f'{path}: image of {ann_file} not found')
        out.append((path, img['width'], img['height'], per[img['id']]))
    return out, dropped


def build_stream(out_dir: str, voc: Sequence[Tuple[str, str]] = (),
                 coco: Sequence[Tuple[str, str, str]] = ()) -> Dict:
    """Lay out a stream of frames by condition, with its annotations.

    Args:
        out_dir (str): Written: ``frames/{condition}/{name}`` (links to the
            photos) and ``annotations.json``.
        voc (Sequence[tuple]): ``(condition, VOC folder)``: its seeded val
            split.
        coco (Sequence[tuple]): ``(condition, instances JSON, image
            folder)``: every image it lists.

    Returns:
        dict: ``{'frames': folder, 'ann_file': path, 'counts':
        {condition: frames}, 'dropped': annotations of other classes}``.
    """
    if not voc and not coco:
        raise ValueError('a stream needs at least one VOC folder or COCO '
                         'file')
    frames_dir = osp.join(out_dir, 'frames')
    if osp.exists(frames_dir) and os.listdir(frames_dir):
        raise FileExistsError(f'{frames_dir} is not empty: choose a new '
                              'out_dir (nothing is overwritten)')
    sources = [(_check_condition(c), voc_frames(root), 0)
               for c, root in voc]
    for c, ann, img_dir in coco:
        found, dropped = coco_frames(ann, img_dir)
        sources.append((_check_condition(c), found, dropped))
    by_name = {c['name']: c['id'] for c in CATEGORIES}
    images, annotations, counts, seen = [], [], {}, set()
    for cond, found, _ in sources:
        os.makedirs(osp.join(frames_dir, cond), exist_ok=True)
        for path, width, height, objs in found:
            rel = f'{cond}/{osp.basename(path)}'
            if rel in seen:
                raise ValueError(f'two frames would be {rel!r}: give the '
                                 'sets different conditions or rename')
            seen.add(rel)
            os.symlink(osp.abspath(path), osp.join(frames_dir, rel))
            # ids from 1: pycocotools reads id 0 as "no match"
            images.append(dict(id=len(images) + 1, file_name=rel,
                               width=width, height=height))
            for o in objs:
                annotations.append(dict(
                    id=len(annotations) + 1, image_id=len(images),
                    category_id=by_name[o['name']], bbox=o['bbox'],
                    area=float(o['bbox'][2] * o['bbox'][3]),
                    iscrowd=o['iscrowd']))
            counts[cond] = counts.get(cond, 0) + 1
    ann_file = osp.join(out_dir, 'annotations.json')
    with open(ann_file, 'w') as f:
        json.dump(dict(images=images, annotations=annotations,
                       categories=CATEGORIES), f)
    return dict(frames=frames_dir, ann_file=ann_file, counts=counts,
                dropped=sum(d for _, _, d in sources))
