"""Real-fog photographs in the PASCAL VOC layout (DAWN, RTTS, any VOC
folder), read as the project's 8 Cityscapes classes."""
import glob
import os.path as osp
import xml.etree.ElementTree as ET
from collections import Counter
from typing import Dict, List, Optional, Sequence

import numpy as np
from mmdet.datasets import XMLDataset
from mmdet.registry import DATASETS
from mmengine.fileio import list_from_file
from mmengine.logging import MMLogger

#: The project's classes (MMDet's ``CityscapesDataset`` order).
CITYSCAPES_CLASSES = ('person', 'rider', 'car', 'truck', 'bus', 'train',
                      'motorcycle', 'bicycle')
#: VOC / RTTS / DAWN names that differ from a Cityscapes class name.
NAME_MAP = {'motorbike': 'motorcycle'}
#: Subsets of the seeded split.
SPLITS = ('train', 'val')


def seeded_split(ids: Sequence[str], subset: str, val_fraction: float = 0.3,
                 seed: int = 0) -> List[str]:
    """One subset of a seeded random train/val split of image ids.

    The ids are sorted, shuffled by ``numpy.random.default_rng(seed)``;
    the first ``round(val_fraction * len(ids))`` of the shuffled order are
    val, the rest train. Both subsets are returned sorted. The split of a
    folder thus depends only on its file names, ``val_fraction`` and
    ``seed``.

    Args:
        ids (Sequence[str]): Image ids (annotation file names without
            ``.xml``).
        subset (str): ``'train'`` or ``'val'``.
        val_fraction (float): Share of val images, in (0, 1).
        seed (int): Seed of the shuffle.

    Returns:
        list[str]: The ids of ``subset``.
    """
    if subset not in SPLITS:
        raise ValueError(f'split must be one of {SPLITS}, got {subset!r}')
    if not 0.0 < val_fraction < 1.0:
        raise ValueError(f'val_fraction must be in (0, 1), got '
                         f'{val_fraction}')
    ids = sorted(ids)
    order = np.random.default_rng(seed).permutation(len(ids))
    num_val = int(round(val_fraction * len(ids)))
    chosen = order[:num_val] if subset == 'val' else order[num_val:]
    return sorted(ids[i] for i in chosen)


@DATASETS.register_module()
class CBNetVOCFogDataset(XMLDataset):
    """A VOC-format detection set (boxes only) with the 8 Cityscapes
    classes: real-fog sets such as DAWN and RTTS, or any VOC folder.

    Layout under ``data_root``: ``Annotations/{id}.xml`` and
    ``JPEGImages/{id}{img_suffix}`` (MMDet's :class:`XMLDataset`, whose
    folders, filtering and category lookups it reuses). The image list is

    * ``ann_file``: a VOC image-set file (one id per line, e.g.
      ``ImageSets/Main/test.txt``), relative to ``data_root``; or
    * with ``ann_file=''``: every ``Annotations/*.xml``, and ``split``
      picks ``'train'`` or ``'val'`` of :func:`seeded_split`
      (``val_fraction``, ``split_seed``) for sets that ship no split.

    Class names: a Cityscapes name is kept, a name of ``name_map`` is
    renamed (default :data:`NAME_MAP`: motorbike -> motorcycle), a name of
    ``ignore_names`` is dropped (object not loaded, counted in the log);
    any other name is a ``ValueError`` listing every such name with its
    count and a file. Objects marked ``<difficult>1`` are loaded with
    ``ignore_flag=1`` (crowd-like for ``CocoMetric``), as MMDet does.

    Boxes are read as written (pixel edges, ``0 <= xmin < xmax <= width``;
    no VOC minus-one shift). A box outside its image is a ``ValueError``
    naming the file and object; with ``clip_to_image=True`` it is clipped
    instead and the number of clipped boxes logged. Also errors naming the
    file: an empty or malformed XML, no ``<size>`` (or a width/height that
    is not a positive integer), an object without ``<name>`` or
    ``<bndbox>`` numbers, a missing image (``check_files``), no annotation
    at all, and no training image left after ``filter_cfg``.

    Evaluate with ``CocoMetric`` without ``ann_file`` and ``'instances'``
    in ``PackDetInputs``' ``meta_keys`` (the ground truth comes from this
    dataset); boxes only, so mask metrics do not apply.

    Args:
        split (str, optional): ``'train'`` or ``'val'``; only with
            ``ann_file=''``.
        val_fraction (float): Val share of the seeded split. Default 0.3.
        split_seed (int): Seed of the split. Default 0.
        name_map (dict, optional): Dataset name -> Cityscapes name;
            default :data:`NAME_MAP`.
        ignore_names (Sequence[str]): Dataset names to drop.
        img_suffix (str): Image file extension (``'.png'`` for RTTS's
            PNGs). Default ``'.jpg'``.
        clip_to_image (bool): Clip boxes outside the image (logged) instead
            of raising. Default False.
        check_files (bool): Check at initialisation that every image
            exists. Default True.
        **kwargs: :class:`XMLDataset` arguments (``data_root``,
            ``ann_file``, ``img_subdir``, ``ann_subdir``, ``filter_cfg``,
            ``pipeline``, ``test_mode``...).
    """

    METAINFO = dict(
        classes=CITYSCAPES_CLASSES,
        # MMDet's CityscapesDataset palette
        palette=[(220, 20, 60), (255, 0, 0), (0, 0, 142), (0, 0, 70),
                 (0, 60, 100), (0, 80, 100), (0, 0, 230), (119, 11, 32)])

    def __init__(self,
                 *args,
                 split: Optional[str] = None,
                 val_fraction: float = 0.3,
                 split_seed: int = 0,
                 name_map: Optional[Dict[str, str]] = None,
                 ignore_names: Sequence[str] = (),
                 img_suffix: str = '.jpg',
                 clip_to_image: bool = False,
                 check_files: bool = True,
                 **kwargs) -> None:
        self.split = split
        self.val_fraction = val_fraction
        self.split_seed = split_seed
        self.name_map = dict(NAME_MAP if name_map is None else name_map)
        self.ignore_names = tuple(ignore_names)
        self.img_suffix = img_suffix
        self.clip_to_image = clip_to_image
        self.check_files = check_files
        # the image and annotation folders sit under data_root itself
        kwargs.setdefault('data_prefix', dict(sub_data_root=''))
        super().__init__(*args, **kwargs)

    def _ann_dir(self) -> str:
        return osp.join(self.sub_data_root, self.ann_subdir)

    def image_ids(self) -> List[str]:
        """The ids this dataset reads (image-set file or seeded split)."""
        if self.ann_file:
            if self.split is not None:
                raise ValueError(
                    f'{type(self).__name__}: give ann_file (an image-set '
                    f'file) or split, not both (ann_file={self.ann_file!r}, '
                    f'split={self.split!r})')
            if not osp.isfile(self.ann_file):
                raise FileNotFoundError(
                    f'image-set file not found: {self.ann_file} (one image '
                    "id per line; or ann_file='' and split='train'/'val' "
                    'for the seeded split of every annotation)')
            return [i for i in list_from_file(self.ann_file) if i.strip()]
        ann_dir = self._ann_dir()
        if not osp.isdir(ann_dir):
            raise FileNotFoundError(
                f'annotation folder not found: {ann_dir} (a VOC folder has '
                f'{self.ann_subdir}/ and {self.img_subdir}/ under data_root)')
        ids = [osp.splitext(osp.basename(p))[0]
               for p in glob.glob(osp.join(ann_dir, '*.xml'))]
        if not ids:
            raise ValueError(f'no .xml annotation in {ann_dir}')
        if self.split is None:
            raise ValueError(
                f"{type(self).__name__}: ann_file='' needs split='train' or "
                "'val' (the seeded split of every annotation)")
        return seeded_split(ids, self.split, self.val_fraction,
                            self.split_seed)

    def load_data_list(self) -> List[dict]:
        """Parse every listed XML; check names, boxes and images.

        Returns:
            list[dict]: One data info per image (``img_path``, ``img_id``,
            ``xml_path``, ``height``, ``width``, ``instances`` with
            ``bbox``, ``bbox_label``, ``ignore_flag``).
        """
        self.cat2label = {
            c: i
            for i, c in enumerate(self._metainfo['classes'])
        }
        bad_targets = {v for v in self.name_map.values()
                       if v not in self.cat2label}
        if bad_targets:
            raise ValueError(f'name_map maps onto {sorted(bad_targets)}, '
                             f'not classes of {self._metainfo["classes"]}')
        self._unknown: Dict[str, List] = {}
        self._stats = Counter()
        data_list = []
        for img_id in self.image_ids():
            data_list.append(self.parse_data_info(dict(
                img_id=img_id,
                file_name=osp.join(self.img_subdir,
                                   img_id + self.img_suffix),
                xml_path=osp.join(self._ann_dir(), f'{img_id}.xml'))))
        if self._unknown:
            listed = ', '.join(
                f'{name!r} ({count}x, e.g. {path})'
                for name, (count, path) in sorted(self._unknown.items()))
            raise ValueError(
                f'{type(self).__name__} at {self.data_root}: class names '
                f'that are not Cityscapes classes: {listed}. Map them '
                f'(name_map={{name: one of {list(self.cat2label)}}}) or '
                'drop them (ignore_names=[...])')
        if self.check_files and self.backend_args is None:
            missing = [d['img_path'] for d in data_list
                       if not osp.isfile(d['img_path'])]
            if missing:
                raise FileNotFoundError(
                    f'{len(missing)} image(s) of {self._ann_dir()} are '
                    f'missing, e.g. {missing[:3]} (img_suffix='
                    f'{self.img_suffix!r})')
        if self._stats:
            MMLogger.get_current_instance().warning(
                f'{type(self).__name__} at {self.data_root}: ' + ', '.join(
                    f'{n} {what}' for what, n in sorted(self._stats.items())))
        return data_list

    def parse_data_info(self, img_info: dict) -> dict:
        """Read one VOC XML into MMDet's data info (see the class doc).

        Args:
            img_info (dict): ``img_id``, ``file_name`` (relative to
                ``data_root``) and ``xml_path``.

        Returns:
            dict: The data info.
        """
        path = img_info['xml_path']
        if not osp.isfile(path):
            raise FileNotFoundError(f'annotation file not found: {path}')
        if osp.getsize(path) == 0:
            raise ValueError(f'{path}: empty file (a VOC annotation is an '
                             '<annotation> XML document)')
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError as err:
            raise ValueError(f'{path}: malformed XML ({err})') from err
        width = _positive_int(root, 'size/width', path)
        height = _positive_int(root, 'size/height', path)
        instances = []
        for k, obj in enumerate(root.findall('object')):
            name = (obj.findtext('name') or '').strip()
            if not name:
                raise ValueError(f'{path}: object {k} has no <name>')
            name = self.name_map.get(name, name)
            if name in self.ignore_names:
                self._stats['objects of ignore_names dropped'] += 1
                continue
            if name not in self.cat2label:
                count, first = self._unknown.get(name, (0, path))
                self._unknown[name] = (count + 1, first)
                continue
            bbox = self._box(obj, k, path, width, height)
            difficult = (obj.findtext('difficult') or '0').strip()
            instances.append(dict(
                bbox=bbox, bbox_label=self.cat2label[name],
                ignore_flag=int(difficult not in ('0', ''))))
        return dict(img_id=img_info['img_id'],
                    img_path=osp.join(self.sub_data_root,
                                      img_info['file_name']),
                    xml_path=path, height=height, width=width,
                    instances=instances)

    def _box(self, obj: ET.Element, k: int, path: str, width: int,
             height: int) -> List[float]:
        """The checked (or clipped) ``[x1, y1, x2, y2]`` of object ``k``."""
        try:
            box = [float(obj.findtext(f'bndbox/{key}'))
                   for key in ('xmin', 'ymin', 'xmax', 'ymax')]
        except (TypeError, ValueError):
            raise ValueError(
                f'{path}: object {k} needs <bndbox> with numeric <xmin> '
                '<ymin> <xmax> <ymax>') from None
        x1, y1, x2, y2 = box
        inside = 0 <= x1 < x2 <= width and 0 <= y1 < y2 <= height
        if inside:
            return box
        clipped = [min(max(x1, 0.0), width), min(max(y1, 0.0), height),
                   min(max(x2, 0.0), width), min(max(y2, 0.0), height)]
        if self.clip_to_image and clipped[0] < clipped[2] and \
                clipped[1] < clipped[3]:
            self._stats['boxes clipped to their image'] += 1
            return clipped
        raise ValueError(
            f'{path}: object {k} box {box} (xmin, ymin, xmax, ymax) is not '
            f'inside its {width}x{height} image or has no area; fix the '
            'XML' + ('' if self.clip_to_image else
                     ', or set clip_to_image=True to clip overhanging boxes'))

    def filter_data(self) -> List[dict]:
        """MMDet's filter, its drops counted in the log (images without
        objects, ``filter_cfg``); an empty training set is an error."""
        data_list = super().filter_data()
        left_out = len(self.data_list) - len(data_list)
        if left_out:
            MMLogger.get_current_instance().info(
                f'{type(self).__name__} at {self.data_root} ({self.split}):'
                f' {len(data_list)} images kept, {left_out} left out by '
                f'filter_cfg={self.filter_cfg} (images without objects, or '
                'smaller than min_size)')
        if not data_list and not self.test_mode:
            raise ValueError(
                f'no training image left in {self.data_root} '
                f'({len(self.data_list)} listed) after filter_cfg='
                f'{self.filter_cfg}')
        return data_list


def _positive_int(root: ET.Element, key: str, path: str) -> int:
    """``int(root.findtext(key))`` > 0, or a ``ValueError`` naming it."""
    text = root.findtext(key)
    try:
        value = int(float(text))
    except (TypeError, ValueError):
        value = None
    if value is None or value <= 0:
        raise ValueError(
            f'{path}: <{key.replace("/", "><")}> must be a positive integer, '
            f'got {text!r}; VOC annotations need <size><width>W</width>'
            '<height>H</height></size> (the image size)')
    return value
