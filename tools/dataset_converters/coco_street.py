"""Make a street-scene instance set from COCO photographs: the COCO
classes that exist on a street mapped onto the project's 8 Cityscapes
classes, a seeded train/val split, COCO json that ``CBNetCityscapesDataset``
reads.

Input: a COCO folder with ``annotations/instances.json`` (any COCO
instances file: ``--ann``) and ``images/`` (``--img-dir``), e.g. a few
hundred photos of COCO 2017 (docs/accuracy.md, "Real masks", says how to
get them). Output in ``OUT``:

* ``annotations/instances_train.json``, ``annotations/instances_val.json``:
  the photos of each split with their annotations of the mapped classes
  (person, car, truck, bus, train, motorcycle, bicycle; COCO has no
  rider), the categories being the project's 8 classes (ids 1-8 in
  ``CITYSCAPES_CLASSES`` order); polygons, RLE crowd regions, boxes, areas
  and ids as COCO has them; the other 73 classes' annotations dropped
  (counted on stdout);
* ``images``: a symbolic link to the input's image folder (``--copy``:
  a copy), so nothing of the photos is rewritten.

The split is seeded and stratified: the photos holding at least one
mapped object and those holding none are each split by
``cbnet_mmdet.datasets.voc_fog.seeded_split`` (their file names sorted,
shuffled by ``numpy.random.default_rng(seed)``, the first
``round(val_fraction * n)`` val), so val holds the same share of street
photos as train. The defaults (``--val-fraction 0.3 --seed 0``) are the
split of docs/accuracy.md.

Usage::

    python tools/dataset_converters/coco_street.py COCO_DIR data/coco_street
"""
import argparse
import json
import os
import os.path as osp
import shutil
import sys
from collections import Counter
from typing import Dict, List, Optional

from cbnet_mmdet.datasets.voc_fog import CITYSCAPES_CLASSES, seeded_split

#: COCO category name -> project class (COCO's own names where they agree).
COCO_TO_STREET = {
    'person': 'person',
    'car': 'car',
    'truck': 'truck',
    'bus': 'bus',
    'train': 'train',
    'motorcycle': 'motorcycle',
    'bicycle': 'bicycle',
}
SPLITS = ('train', 'val')


def street_categories() -> List[dict]:
    """The 8 project classes as COCO categories, ids 1-8."""
    return [dict(id=i, name=name, supercategory='street')
            for i, name in enumerate(CITYSCAPES_CLASSES, 1)]


def _check_entries(entries: list, key: str, fields) -> None:
    """Every entry of ``coco[key]`` a dict with ``fields``."""
    for k, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise ValueError(f'{key}[{k}] is {type(entry).__name__} '
                             f'{entry!r:.60}, not an object')
        lacking = [f for f in fields if f not in entry]
        if lacking:
            raise ValueError(f'{key}[{k}] (id {entry.get("id")}) has no '
                             f'{lacking}')


def convert(coco: dict, val_fraction: float = 0.3, seed: int = 0,
            name_map: Optional[Dict[str, str]] = None) -> dict:
    """Split and relabel one COCO instances dict.

    Args:
        coco (dict): COCO instances (``images``, ``annotations``,
            ``categories``).
        val_fraction (float): Val share of each stratum, in (0, 1).
        seed (int): Seed of the split.
        name_map (dict, optional): COCO name -> project class (default
            :data:`COCO_TO_STREET`).

    Returns:
        dict: ``{'train': coco_dict, 'val': coco_dict, 'stats': {...}}``.

    Raises:
        ValueError: Malformed input (missing keys, entries that are no
            objects or lack their fields, duplicate image ids or file
            names, an annotation of an unknown image or category, a map
            onto an unknown class, annotations none of which is of a
            street class).
    """
    name_map = dict(COCO_TO_STREET if name_map is None else name_map)
    bad = sorted(set(name_map.values()) - set(CITYSCAPES_CLASSES))
    if bad:
        raise ValueError(f'name_map maps onto {bad}, not classes of '
                         f'{CITYSCAPES_CLASSES}')
    for key in ('images', 'annotations', 'categories'):
        if not isinstance(coco.get(key), list):
            raise ValueError(f'not a COCO instances file: no {key!r} list')
    _check_entries(coco['images'], 'images', ('id', 'file_name'))
    _check_entries(coco['categories'], 'categories', ('id', 'name'))
    _check_entries(coco['annotations'], 'annotations',
                   ('image_id', 'category_id'))
    images = {}
    for img in coco['images']:
        if img['id'] in images:
            raise ValueError(f'image id {img["id"]} listed twice')
        images[img['id']] = img
    names = [img['file_name'] for img in coco['images']]
    if len(set(names)) != len(names):
        raise ValueError('two images share a file_name')
    # COCO's names are lower case; another file's 'Car' is COCO's 'car'
    cat_names = {c['id']: str(c['name']).strip().lower()
                 for c in coco['categories']}
    name_map = {k.strip().lower(): v for k, v in name_map.items()}
    target_id = {c['name']: c['id'] for c in street_categories()}
    kept: Dict[int, List[dict]] = {i: [] for i in images}
    dropped = Counter()
    kept_per_class = Counter()
    for ann in coco['annotations']:
        if ann['image_id'] not in images:
            raise ValueError(f'annotation {ann.get("id")} names image '
                             f'{ann["image_id"]}, which is not listed')
        if ann['category_id'] not in cat_names:
            raise ValueError(f'annotation {ann.get("id")} has category '
                             f'{ann["category_id"]}, which is not listed')
        name = cat_names[ann['category_id']]
        if name not in name_map:
            dropped[name] += 1
            continue
        target = name_map[name]
        kept[ann['image_id']].append(
            dict(ann, category_id=target_id[target]))
        kept_per_class[target] += 1
    if coco['annotations'] and not kept_per_class:
        found = sorted({c['name'] for c in coco['categories']})
        raise ValueError(
            f'no annotation of a street class: the categories are '
            f'{found[:20]}{" ..." if len(found) > 20 else ""}; the map '
            f'reads {sorted(name_map)} (give name_map for other names)')
    # strata: photos with a street object (crowd regions alone do not
    # count) and the rest, each split alike
    street = [images[i]['file_name'] for i, anns in kept.items()
              if any(not a.get('iscrowd', 0) for a in anns)]
    other = sorted(set(names) - set(street))
    by_name = {img['file_name']: img for img in coco['images']}
    out = {}
    for split in SPLITS:
        chosen = []
        for stratum in (street, other):
            if len(stratum) >= 2:
                chosen += seeded_split(stratum, split, val_fraction, seed)
            elif split == 'train':  # one photo cannot be split
                chosen += stratum
        chosen = sorted(chosen)
        split_images = [by_name[n] for n in chosen]
        out[split] = dict(
            images=split_images,
            annotations=[a for img in split_images for a in kept[img['id']]],
            categories=street_categories())
    out['stats'] = dict(
        images={s: len(out[s]['images']) for s in SPLITS},
        street_images={s: len(set(street) & {
            i['file_name'] for i in out[s]['images']}) for s in SPLITS},
        instances={s: dict(Counter(
            CITYSCAPES_CLASSES[a['category_id'] - 1]
            for a in out[s]['annotations'])) for s in SPLITS},
        kept=dict(kept_per_class), dropped=sum(dropped.values()))
    return out


def parse_args(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__.split('\n\n')[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__.split('\n\n', 1)[1])
    parser.add_argument('src', help='COCO folder (annotations/, images/)')
    parser.add_argument('out', help='output folder')
    parser.add_argument('--ann', default='annotations/instances.json',
                        help='COCO instances file, relative to SRC')
    parser.add_argument('--img-dir', default='images',
                        help='image folder, relative to SRC')
    parser.add_argument('--val-fraction', type=float, default=0.3)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--copy', action='store_true',
                        help='copy the images instead of linking them')
    return parser.parse_args(argv)


def main(argv=None) -> dict:
    args = parse_args(argv)
    ann = osp.join(args.src, args.ann)
    img_dir = osp.abspath(osp.join(args.src, args.img_dir))
    if not osp.isfile(ann):
        raise FileNotFoundError(f'{ann} not found (--ann)')
    if not osp.isdir(img_dir):
        raise FileNotFoundError(f'{img_dir} not found (--img-dir)')
    with open(ann) as f:
        try:
            coco = json.load(f)
        except json.JSONDecodeError as err:
            raise ValueError(f'{ann}: not JSON ({err})') from err
    result = convert(coco, args.val_fraction, args.seed)
    missing = [i['file_name'] for s in SPLITS for i in result[s]['images']
               if not osp.isfile(osp.join(img_dir, i['file_name']))]
    if missing:
        raise FileNotFoundError(
            f'{len(missing)} image(s) of {ann} are not in {img_dir}, e.g. '
            f'{missing[:3]}')
    os.makedirs(osp.join(args.out, 'annotations'), exist_ok=True)
    for split in SPLITS:
        with open(osp.join(args.out, 'annotations',
                           f'instances_{split}.json'), 'w') as f:
            json.dump(result[split], f)
    link = osp.join(args.out, 'images')
    if osp.islink(link):
        os.remove(link)
    if args.copy:
        shutil.copytree(img_dir, link, dirs_exist_ok=True)
    elif not osp.exists(link):
        os.symlink(img_dir, link)
    elif osp.realpath(link) != img_dir:
        raise FileExistsError(f'{link} exists and is not a link to '
                              f'{img_dir}: remove it or use --copy')
    stats = result['stats']
    for split in SPLITS:
        print(f'{split}: {stats["images"][split]} photos '
              f'({stats["street_images"][split]} with street objects), '
              f'instances {stats["instances"][split]}')
    print(f'dropped {stats["dropped"]} annotations of other COCO classes; '
          f'split: seed {args.seed}, val fraction {args.val_fraction}; '
          f'written to {args.out}')
    return stats


if __name__ == '__main__':
    main(sys.argv[1:])
