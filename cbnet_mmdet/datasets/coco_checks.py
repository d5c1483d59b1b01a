"""Value checks of a COCO instance annotation file before training.

:func:`check_coco` reads the whole file's content (types AND values, not
only shapes) before MMDetection's ``CocoDataset`` parses it, and either

* raises ONE ``ValueError`` naming the file, the entry (annotation id and
  its image, image index, category) and what to fix, for input that would
  train on wrong data or crash a library: top level not a JSON object,
  malformed or duplicate categories, image ids not unique integers,
  duplicate file names, non-positive image sizes, annotation ids not
  unique integers, an ``image_id`` or ``category_id`` that is not an
  integer, ``iscrowd`` other than the integer 0 or 1 (a string ``"0"``
  would silently make an ignore region), a box that is not 4 finite
  numbers, a missing area, polygons with non-finite coordinates or
  coordinates outside the image (``1e30`` / NaN crash pycocotools),
  RLE counts that do not sum to exactly height x width (pycocotools
  decodes whatever lies in memory after them), or a box that disagrees
  with its mask by more than the tolerance; or
* drops the annotation, which is what MMDetection does silently, and
  counts it per reason (:data:`DROP_REASONS`): ``"ignore": true``, an
  ``image_id`` not in ``images``, a ``category_id`` not in
  ``categories``, a category that is not one of the dataset's classes, a
  box fully outside its image, a box narrower or lower than 1 pixel, an
  area <= 0. With ``strict=True`` any drop is an error instead.

Categories are matched to the dataset's classes BY NAME: the checked dict
lists one category per class, in the classes' order, so MMDetection's
``cat2label`` gives class ``i`` label ``i`` even when the file lists them in
another order or lacks one (that class gets a placeholder category with an
id no annotation uses, so it has no instances; :class:`CheckResult` lists
it in ``missing_classes``).
"""
import json
import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence

from mmdet.datasets.api_wrappers import COCO
from pycocotools import mask as mask_utils

#: Why an annotation is dropped (key: what the log and errors print).
DROP_REASONS = {
    'ignore': 'marked "ignore": true',
    'unknown_image': 'image_id not in "images"',
    'unknown_category': 'category_id not in "categories"',
    'other_class': 'category is not one of the dataset classes',
    'outside_image': 'box fully outside its image',
    'below_1px': 'box width or height < 1 px',
    'zero_area': 'area <= 0',
}
#: Largest distance (pixels) by which a box edge may differ from its
#: mask's extent, and the same as a fraction of the box side (the larger
#: of the two applies); polygon points may lie this far outside the image.
BBOX_TOLERANCE_PX = 2.0
BBOX_TOLERANCE_REL = 0.1
#: Annotation ids listed per drop reason in the log (counts always given).
MAX_LISTED = 5


@dataclass
class CheckResult:
    """What :func:`check_coco` found.

    Attributes:
        coco (dict): The file's content with the dropped annotations
            removed and ``categories`` one per class, in the classes'
            order (placeholders for missing classes).
        drops (Counter): Dropped annotations per reason (keys of
            :data:`DROP_REASONS`).
        dropped_ids (dict[str, list]): Their annotation ids per reason.
        missing_classes (list[str]): Classes no category is named after.
        annotations (int): Annotations in the file.
    """
    coco: dict
    drops: Counter = field(default_factory=Counter)
    dropped_ids: Dict[str, list] = field(default_factory=dict)
    missing_classes: List[str] = field(default_factory=list)
    annotations: int = 0

    def drop_summary(self) -> str:
        """``'2 box fully outside its image (ids 7, 9), ...'``."""
        parts = []
        for reason, count in sorted(self.drops.items()):
            ids = self.dropped_ids[reason]
            listed = ', '.join(str(i) for i in ids[:MAX_LISTED])
            more = ' ...' if len(ids) > MAX_LISTED else ''
            parts.append(f'{count} {DROP_REASONS[reason]} (ids {listed}'
                         f'{more})')
        return ', '.join(parts)


class CheckedCOCO(COCO):
    """MMDetection's COCO API over an already read and checked dict.

    ``CocoDataset.load_data_list`` calls ``COCOAPI(path)``; a dataset that
    sets ``COCOAPI = functools.partial(CheckedCOCO, checked_dict)`` gets
    this index instead of one from the unchecked file.

    Args:
        dataset (dict): COCO content (``images``, ``annotations``,
            ``categories``).
        annotation_file (str, optional): Ignored (the file was read).
    """

    def __init__(self, dataset: dict, annotation_file=None) -> None:
        super().__init__()
        self.dataset = dataset
        self.createIndex()
        self.img_ann_map = self.imgToAnns
        self.cat_img_map = self.catToImgs


def is_int(value) -> bool:
    """A JSON integer (``bool`` is no integer here)."""
    return isinstance(value, int) and not isinstance(value, bool)


def is_number(value) -> bool:
    """A finite JSON number."""
    return isinstance(value, (int, float)) and not isinstance(
        value, bool) and math.isfinite(value)


def rle_string_counts(counts: str) -> List[int]:
    """Run lengths of a compressed COCO RLE string.

    The format of ``rleFrString`` in pycocotools' ``maskApi.c``: 5 bits per
    character (offset 48), a continuation bit, sign extension, and each
    count after the second stored as the difference to the count two
    before it.

    Raises:
        ValueError: A character outside the format, a number cut off, or
            a negative run length.
    """
    runs: List[int] = []
    pos = 0
    while pos < len(counts):
        value, shift, more = 0, 0, True
        while more:
            if pos >= len(counts):
                raise ValueError('the string ends inside a number')
            code = ord(counts[pos]) - 48
            if not 0 <= code < 64:
                raise ValueError(f'character {counts[pos]!r}')
            value |= (code & 0x1f) << shift
            more = bool(code & 0x20)
            pos += 1
            shift += 5
            if not more and code & 0x10:
                value |= -1 << shift
        if len(runs) > 2:
            value += runs[-2]
        if value < 0:
            raise ValueError(f'negative run length {value}')
        runs.append(value)
    return runs


def segmentation_problem(segm, height: int, width: int) -> str:
    """What is wrong with a segmentation's format and values ('' if
    nothing): polygons of finite numbers, even length >= 6; RLE of the
    image's size whose counts sum to exactly ``height * width``."""
    if isinstance(segm, list):
        if not segm:
            return 'empty segmentation'
        for poly in segm:
            if not isinstance(poly, list) or len(poly) < 6 or len(poly) % 2:
                return ('polygons need an even number (>= 6) of '
                        f'coordinates, got {str(poly)[:60]}')
            if not all(is_number(v) for v in poly):
                bad = next(v for v in poly if not is_number(v))
                return (f'polygon coordinates must be finite numbers, got '
                        f'{bad!r}')
        return ''
    if isinstance(segm, dict):
        size = [height, width]
        if list(segm.get('size', [])) != size:
            return (f'RLE size {segm.get("size")} is not the image size '
                    f'{size}')
        counts = segm.get('counts')
        try:
            if isinstance(counts, str):
                runs = rle_string_counts(counts)
            elif isinstance(counts, list) and all(
                    is_int(c) and c >= 0 for c in counts):
                runs = counts
            else:
                raise ValueError('neither a string nor non-negative ints')
        except ValueError:
            return f'undecodable RLE counts {str(counts)[:40]!r}'
        if sum(runs) != height * width:
            return (f'RLE counts sum to {sum(runs)} pixels, not height x '
                    f'width = {height * width} (re-encode the mask with '
                    f'pycocotools.mask.encode)')
        return ''
    return f'segmentation must be polygons or RLE, got {type(segm).__name__}'


def mask_extent(segm, height: int, width: int) -> Optional[List[float]]:
    """``[x1, y1, x2, y2]`` of a checked segmentation (None: empty)."""
    if isinstance(segm, list):
        xs = [v for poly in segm for v in poly[0::2]]
        ys = [v for poly in segm for v in poly[1::2]]
        return [min(xs), min(ys), max(xs), max(ys)]
    counts = segm['counts']
    if isinstance(counts, list):
        rle = mask_utils.frPyObjects(segm, height, width)
    else:
        rle = dict(size=[height, width], counts=counts.encode())
    if not mask_utils.area(rle):
        return None
    x, y, w, h = mask_utils.toBbox(rle).tolist()
    return [x, y, x + w, y + h]


def geometry_problem(ann: dict, img: dict) -> str:
    """Polygon points inside the image and box vs mask extent ('' when
    consistent); for annotations that passed the other checks."""
    segm = ann.get('segmentation')
    if not segm:
        return ''
    height, width = img['height'], img['width']
    tol = BBOX_TOLERANCE_PX
    if isinstance(segm, list):
        for poly in segm:
            if not (all(-tol <= v <= width + tol for v in poly[0::2])
                    and all(-tol <= v <= height + tol for v in poly[1::2])):
                return (f'polygon points outside the {width}x{height} '
                        f'image, e.g. {str(poly)[:60]} (clip them to the '
                        f'image)')
    extent = mask_extent(segm, height, width)
    x, y, w, h = ann['bbox']
    box = [x, y, x + w, y + h]
    if extent is None:
        return f'bbox {ann["bbox"]} has an empty mask'
    sides = (w, h, w, h)
    if any(
            abs(a - b) > max(tol, BBOX_TOLERANCE_REL * s)
            for a, b, s in zip(box, extent, sides)):
        ext = [round(v, 1) for v in extent]
        return (f'bbox {ann["bbox"]} disagrees with its mask, which spans '
                f'x1, y1, x2, y2 = {ext} (tolerance {tol:g} px or '
                f'{BBOX_TOLERANCE_REL:g} of the side); recompute the box '
                f'from the mask (pycocotools.mask.toBbox)')
    return ''


def annotation_problem(ann: dict, img: Optional[dict]) -> str:
    """Errors of one annotation's types and values ('' when none);
    ``img`` is its image entry, None when ``image_id`` is unknown."""
    for key in ('image_id', 'category_id'):
        if not is_int(ann.get(key)):
            return (f'{key} must be an integer, got {ann.get(key)!r} '
                    f'({type(ann.get(key)).__name__})')
    iscrowd = ann.get('iscrowd', 0)
    if not is_int(iscrowd) or iscrowd not in (0, 1):
        return (f'iscrowd must be the integer 0 or 1, got {iscrowd!r} '
                f'({type(iscrowd).__name__}); write 0 (an instance) or 1 (a '
                f'crowd region, ignored in training), without quotes')
    bbox = ann.get('bbox')
    if not isinstance(bbox, (list, tuple)) or len(bbox) != 4 or not all(
            is_number(v) for v in bbox):
        return f'bbox must be 4 finite numbers [x, y, w, h], got {bbox!r}'
    if not is_number(ann.get('area')):
        return f'area must be a finite number, got {ann.get("area")!r}'
    if 'segmentation' in ann and img is not None:
        return segmentation_problem(ann['segmentation'], img['height'],
                                    img['width'])
    return ''


def drop_reason(ann: dict, img: Optional[dict], cat_names: Dict[int, str],
                classes: Sequence[str]) -> str:
    """Why MMDetection would leave out an annotation ('' to keep it); the
    same tests as ``CocoDataset.parse_data_info``."""
    if ann.get('ignore', False):
        return 'ignore'
    if img is None:
        return 'unknown_image'
    if ann['category_id'] not in cat_names:
        return 'unknown_category'
    if cat_names[ann['category_id']] not in classes:
        return 'other_class'
    x, y, w, h = ann['bbox']
    inter_w = max(0, min(x + w, img['width']) - max(x, 0))
    inter_h = max(0, min(y + h, img['height']) - max(y, 0))
    if inter_w * inter_h == 0:
        return 'outside_image'
    if w < 1 or h < 1:
        return 'below_1px'
    if ann['area'] <= 0:
        return 'zero_area'
    return ''


class _Checker:
    """One file's checks; ``fail`` raises the one error."""

    def __init__(self, ann_file: str, classes: Sequence[str]) -> None:
        self.ann_file = ann_file
        self.classes = tuple(classes)

    def fail(self, where: str, problem: str) -> None:
        raise ValueError(f'annotation file {self.ann_file}: {where}: '
                         f'{problem}')

    def top_level(self, coco) -> None:
        if not isinstance(coco, dict):
            self.fail(
                'top level', f'must be a JSON object with "images", '
                f'"annotations" and "categories", got a '
                f'{type(coco).__name__} (convert the dataset with '
                f'tools/dataset_converters/cityscapes.py)')
        for key in ('images', 'annotations', 'categories'):
            if not isinstance(coco.get(key), list):
                self.fail(f'"{key}"', f'must be a list, got '
                          f'{type(coco.get(key)).__name__}')

    def categories(self, cats: list) -> Dict[int, str]:
        names: Dict[int, str] = {}
        for i, cat in enumerate(cats):
            if not isinstance(cat, dict) or not is_int(cat.get('id')) or \
                    not isinstance(cat.get('name'), str):
                self.fail(f'categories[{i}]', f'must be {{"id": int, '
                          f'"name": str}}, got {str(cat)[:80]}')
            if cat['id'] in names:
                self.fail(f'categories[{i}]', f'category id {cat["id"]} '
                          f'is listed twice')
            if cat['name'] in names.values():
                self.fail(f'categories[{i}]', f'category name '
                          f'{cat["name"]!r} is listed twice; labels are '
                          f'given by name, so each name must be unique')
            names[cat['id']] = cat['name']
        return names

    def images(self, images: list) -> Dict[int, dict]:
        by_id: Dict[int, dict] = {}
        files = set()
        for i, img in enumerate(images):
            if not isinstance(img, dict):
                self.fail(f'images[{i}]', f'must be an object, got '
                          f'{str(img)[:60]}')
            where = f'image {i} ({img.get("file_name")!r})'
            if not is_int(img.get('id')):
                kind = type(img.get('id')).__name__
                self.fail(where, f'id must be an integer, got '
                          f'{img.get("id")!r} ({kind})')
            if img['id'] in by_id:
                self.fail(where, f'id {img["id"]} is also the id of '
                          f'{by_id[img["id"]].get("file_name")!r}; image '
                          f'ids must be unique (or one image is trained '
                          f'with the other\'s instances)')
            name = img.get('file_name')
            if not isinstance(name, str) or not name:
                self.fail(where, 'file_name must be a non-empty string')
            if name in files:
                self.fail(where, 'file_name is listed twice; list each '
                          'image once with all its annotations')
            for key in ('height', 'width'):
                if not is_int(img.get(key)) or img[key] < 1:
                    self.fail(where, f'{key} must be a positive integer, '
                              f'got {img.get(key)!r}')
            by_id[img['id']] = img
            files.add(name)
        return by_id

    def annotation_error(self, ann: dict, img: Optional[dict],
                         problem: str) -> None:
        if img is None:
            where = f'annotation {ann.get("id")} (image_id ' \
                f'{ann.get("image_id")!r})'
        else:
            where = (f'annotation {ann.get("id")} of image '
                     f'{img.get("file_name")!r} (id {img.get("id")})')
        self.fail(where, problem)


def check_coco(coco, ann_file: str, classes: Sequence[str],
               strict: bool = False) -> CheckResult:
    """Check a COCO instance dict and drop what MMDetection would drop.

    Args:
        coco: The parsed JSON of ``ann_file``.
        ann_file (str): Its path (for the messages).
        classes (Sequence[str]): The dataset's class names; label ``i`` is
            the category named ``classes[i]``.
        strict (bool): Raise on the first drop reason instead of dropping.

    Returns:
        CheckResult: The cleaned dict and the drops per reason.

    Raises:
        ValueError: See the module docstring; the message names the file,
            the entry and the fix.
    """
    checker = _Checker(ann_file, classes)
    checker.top_level(coco)
    cat_names = checker.categories(coco['categories'])
    images = checker.images(coco['images'])
    result = CheckResult(coco=coco, annotations=len(coco['annotations']))
    kept, ann_ids = [], set()
    for i, ann in enumerate(coco['annotations']):
        if not isinstance(ann, dict):
            checker.fail(f'annotations[{i}]', f'must be an object, got '
                         f'{str(ann)[:60]}')
        img = images.get(ann.get('image_id'))
        if not is_int(ann.get('id')) or ann['id'] in ann_ids:
            checker.annotation_error(
                ann, img, 'id must be an integer unique among the '
                'annotations (renumber them from 1)')
        ann_ids.add(ann['id'])
        problem = annotation_problem(ann, img)
        if problem:
            checker.annotation_error(ann, img, problem)
        reason = drop_reason(ann, img, cat_names, checker.classes)
        if reason:
            result.drops[reason] += 1
            result.dropped_ids.setdefault(reason, []).append(ann['id'])
            continue
        problem = geometry_problem(ann, img)
        if problem:
            checker.annotation_error(ann, img, problem)
        kept.append(ann)
    if strict and result.drops:
        raise ValueError(
            f'annotation file {ann_file}: strict mode: '
            f'{sum(result.drops.values())} annotation(s) would be dropped: '
            f'{result.drop_summary()}; fix them, or train without --strict '
            f'(strict=False) to drop them with a log line')
    named = {name: cid for cid, name in cat_names.items()}
    result.missing_classes = [c for c in checker.classes if c not in named]
    # a missing class keeps its label: a placeholder category (an id no
    # annotation uses) holds its place in MMDetection's `cat2label`
    unused = max(cat_names, default=0) + 1
    for offset, name in enumerate(result.missing_classes):
        named[name] = unused + offset
    categories = [dict(id=named[c], name=c) for c in checker.classes]
    result.coco = dict(coco, annotations=kept, categories=categories)
    return result


def read_json(path: str) -> object:
    """Parse a local JSON file; ``ValueError`` naming it when invalid."""
    with open(path, encoding='utf-8') as f:
        try:
            return json.load(f)
        except (json.JSONDecodeError, UnicodeDecodeError) as err:
            raise ValueError(f'annotation file {path} is not valid JSON: '
                             f'{err}') from err
