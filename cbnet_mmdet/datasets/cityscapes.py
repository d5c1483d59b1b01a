"""Cityscapes instance dataset with clear errors on malformed input."""
import json
import math
import os.path as osp
from typing import List

from mmdet.datasets import CityscapesDataset
from pycocotools import mask as mask_utils
from mmdet.registry import DATASETS

from .transforms.load_image_from_file import with_checked_loader

#: Missing images listed in the error message (the count is always given).
MAX_LISTED = 5


@DATASETS.register_module()
class CBNetCityscapesDataset(CityscapesDataset):
    """MMDetection's 8-class ``CityscapesDataset`` that fails early and
    clearly.

    Reads the converter's COCO JSON
    (``annotations/instancesonly_filtered_gtFine_{split}.json``) like its
    parent, and additionally raises

    * ``FileNotFoundError`` naming the annotation file or image folder when
      it is missing, and naming the images (first :data:`MAX_LISTED` and the
      count) listed in the annotations but absent on disk;
    * ``ValueError`` naming the annotation file when it is not valid JSON,
      when an annotation is malformed (box not 4 finite numbers; polygon
      with fewer than 3 points or odd length; RLE of another size than
      its image or undecodable; empty segmentation) - with the annotation
      id and image - or when no training image is left after
      ``filter_cfg``.

    Images are loaded with :class:`CBNetLoadImageFromFile` (missing,
    corrupt or wrongly sized image: an error naming the file) wherever the
    pipeline names MMCV's ``LoadImageFromFile`` - the name MMDetection's
    ``DetInferencer`` and corruption benchmark look for in the config.

    Args:
        check_files (bool): Check at initialisation that every image
            exists (local files only; skipped with ``backend_args``).
            Default True.
        **kwargs: ``CityscapesDataset`` / ``CocoDataset`` arguments.
    """

    #: Data-info keys of the image files ``check_files`` looks for.
    image_path_keys = ('img_path', )

    def __init__(self, *args, check_files: bool = True, **kwargs) -> None:
        self.check_files = check_files
        if kwargs.get('pipeline'):
            kwargs['pipeline'] = with_checked_loader(kwargs['pipeline'])
        super().__init__(*args, **kwargs)

    def load_data_list(self) -> List[dict]:
        """Load the annotations, then check the images they name.

        Returns:
            list[dict]: One data info per image (see ``CocoDataset``).
        """
        local = self.backend_args is None
        if local and not osp.isfile(self.ann_file):
            raise FileNotFoundError(
                f'annotation file not found: {self.ann_file} (convert '
                f'gtFine with tools/dataset_converters/cityscapes.py)')
        try:
            data_list = super().load_data_list()
        except json.JSONDecodeError as err:
            raise ValueError(f'annotation file {self.ann_file} is not valid '
                             f'JSON: {err}') from err
        except (KeyError, TypeError) as err:
            raise ValueError(f'annotation file {self.ann_file} is not in COCO '
                             f'format: {err!r}') from err
        if self.check_files and local:
            self._check_images(data_list)
        return data_list

    def parse_data_info(self, raw_data_info: dict) -> dict:
        """Check every annotation of an image, then parse it as MMDet does.

        Args:
            raw_data_info (dict): ``raw_img_info`` and ``raw_ann_info``.

        Returns:
            dict: MMDetection's data info.
        """
        img = raw_data_info['raw_img_info']
        for ann in raw_data_info['raw_ann_info']:
            problem = annotation_problem(ann, img)
            if problem:
                raise ValueError(
                    f'annotation file {self.ann_file}: annotation '
                    f'{ann.get("id")} of image {img.get("file_name")!r} '
                    f'(id {img.get("id")}): {problem}')
        return super().parse_data_info(raw_data_info)

    def filter_data(self) -> List[dict]:
        """MMDet's filter; an empty training set is an error naming the
        annotation file (MMEngine fails later without a name)."""
        data_list = super().filter_data()
        if not data_list and not self.test_mode:
            raise ValueError(
                f'no training image left from {self.ann_file} '
                f'({len(self.data_list)} listed) after filter_cfg='
                f'{self.filter_cfg} (images without non-crowd instances '
                f'are dropped)')
        return data_list

    def _check_images(self, data_list: List[dict]) -> None:
        """Raise ``FileNotFoundError`` naming missing images/folders."""
        folder = self.data_prefix.get('img', '')
        if folder and not osp.isdir(folder):
            raise FileNotFoundError(
                f'image folder not found: {folder} (data_root + '
                f'data_prefix.img of {type(self).__name__})')
        missing = [
            info[key] for info in data_list for key in self.image_path_keys
            if not osp.isfile(info[key])
        ]
        if missing:
            listed = '\n  '.join(missing[:MAX_LISTED])
            raise FileNotFoundError(
                f'{len(missing)} image(s) listed in {self.ann_file} are '
                f'missing, e.g.:\n  {listed}')


def annotation_problem(ann: dict, img: dict) -> str:
    """What is wrong with one COCO annotation ('' when nothing).

    Args:
        ann (dict): A COCO annotation (``bbox`` x, y, w, h in pixels,
            ``segmentation`` polygons or RLE).
        img (dict): Its image entry (``height``, ``width``).

    Returns:
        str: A description of the first problem found, or ``''``.
    """
    bbox = ann.get('bbox')
    if not isinstance(bbox, (list, tuple)) or len(bbox) != 4 or not all(
            isinstance(v, (int, float)) and math.isfinite(v) for v in bbox):
        return f'bbox must be 4 finite numbers [x, y, w, h], got {bbox!r}'
    if 'segmentation' not in ann:
        return ''
    segm = ann['segmentation']
    if isinstance(segm, list):
        if not segm:
            return 'empty segmentation'
        for poly in segm:
            if not isinstance(poly, list) or len(poly) < 6 or len(poly) % 2:
                return ('polygons need an even number (>= 6) of '
                        f'coordinates, got {str(poly)[:60]}')
        return ''
    if isinstance(segm, dict):
        size = [img.get('height'), img.get('width')]
        if list(segm.get('size', [])) != size:
            return (f'RLE size {segm.get("size")} is not the image size '
                    f'{size}')
        counts = segm.get('counts')
        try:
            if isinstance(counts, list):
                mask_utils.frPyObjects(segm, *size)
            else:
                rle = dict(size=size, counts=counts.encode()
                           if isinstance(counts, str) else counts)
                if mask_utils.area(rle) > size[0] * size[1]:
                    raise ValueError
                mask_utils.decode(rle)
        except Exception:  # noqa: B902  (pycocotools raises many types)
            return f'undecodable RLE counts {str(counts)[:40]!r}'
        return ''
    return f'segmentation must be polygons or RLE, got {type(segm).__name__}'
