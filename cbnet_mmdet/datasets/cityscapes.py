"""Cityscapes instance dataset with clear errors on malformed input."""
import functools
import logging
import os.path as osp
from typing import List

from mmdet.datasets import CityscapesDataset
from mmdet.registry import DATASETS
from mmengine.fileio import get_local_path
from mmengine.logging import print_log

from .coco_checks import CheckedCOCO, check_coco, read_json

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
      when its content is wrong (the value checks of
      :mod:`~cbnet_mmdet.datasets.coco_checks`: categories matched to the
      classes by name, unique integer ids, ``iscrowd`` 0/1, boxes of 4
      finite numbers agreeing with their masks, finite polygons inside the
      image, RLE of the image's size summing to height x width ...) - with
      the entry (annotation id and image) and the fix - or when no
      training image is left after ``filter_cfg``.

    What MMDetection drops silently (unknown category, box outside its
    image or below 1 px, area 0, ``ignore``, unknown image) is dropped
    with a warning giving the count per reason (``strict=True``: an error
    instead), and every full initialisation logs one summary line: images,
    instances, crowd regions, drops per reason, images left out by
    ``filter_cfg``. The counts stay in :attr:`load_report`.

    The pipeline runs as the config names it. The project's configs load
    training images with :class:`CBNetLoadImageFromFile` (a missing,
    corrupt or wrongly sized image: an error naming the file) and test
    images with MMCV's ``LoadImageFromFile`` reading through the
    ``cbnet_image`` file backend, then ``CBNetCheckImage`` (the name
    MMDetection's ``DetInferencer`` looks for in the test pipeline).

    Args:
        check_files (bool): Check at initialisation that every image
            exists (local files only; skipped with ``backend_args``).
            Default True.
        strict (bool): Raise instead of dropping annotations
            (``tools/train.py --strict``). Default False.
        **kwargs: ``CityscapesDataset`` / ``CocoDataset`` arguments.
    """

    #: Data-info keys of the image files ``check_files`` looks for.
    image_path_keys = ('img_path', )

    def __init__(self,
                 *args,
                 check_files: bool = True,
                 strict: bool = False,
                 **kwargs) -> None:
        self.check_files = check_files
        self.strict = strict
        #: Counts of the last load: ``listed_images``, ``annotations`` (in
        #: the file), ``drops`` (per reason), ``filtered_images``,
        #: ``filtered_instances`` (left out by ``filter_cfg``), ``images``,
        #: ``instances`` and ``crowd`` (loaded, after the filter).
        self.load_report: dict = {}
        super().__init__(*args, **kwargs)

    def _missing_annotations_fix(self) -> str:
        """What makes the missing COCO file, for the folder at hand: its
        ``gtFine`` converted, when the folder has one; otherwise where the
        data comes from (Cityscapes, or the generated stand-in)."""
        root = self.data_root or osp.dirname(
            osp.dirname(osp.abspath(self.ann_file)))
        if osp.isdir(osp.join(root, 'gtFine')):
            return (f'convert its gtFine: python tools/dataset_converters/'
                    f'cityscapes.py {root} (the generated stand-in: python '
                    f'tools/misc/generate_cityscapes_like.py {root} '
                    f'--convert)')
        return (f'{root} has no gtFine: get Cityscapes into it and convert '
                f'gtFine with tools/dataset_converters/cityscapes.py '
                f'(docs/dataset.md), or generate the stand-in there: python '
                f'tools/misc/generate_cityscapes_like.py {root} --convert')

    def load_data_list(self) -> List[dict]:
        """Load the annotations, then check the images they name.

        Returns:
            list[dict]: One data info per image (see ``CocoDataset``).
        """
        local = self.backend_args is None
        if local and not osp.isfile(self.ann_file):
            raise FileNotFoundError(
                f'annotation file not found: {self.ann_file} '
                f'({self._missing_annotations_fix()})')
        with get_local_path(self.ann_file,
                            backend_args=self.backend_args) as path:
            try:
                coco = read_json(path)
            except ValueError as err:  # names the local copy: name ours
                raise ValueError(str(err).replace(
                    path, str(self.ann_file))) from err
        checked = check_coco(coco, self.ann_file, self.metainfo['classes'],
                             self.strict)
        self.load_report = dict(listed_images=len(coco['images']),
                                annotations=checked.annotations,
                                drops=dict(checked.drops))
        if checked.drops:
            print_log(
                f'{type(self).__name__}: dropped '
                f'{sum(checked.drops.values())} of {checked.annotations} '
                f'annotations of {self.ann_file}: '
                f'{checked.drop_summary()} (strict=True / --strict to '
                f'stop instead)', logger='current', level=logging.WARNING)
        if checked.missing_classes:
            print_log(
                f'{type(self).__name__}: no category of {self.ann_file} is '
                f'named {checked.missing_classes}: no instances of these '
                f'classes (the others keep their labels)', logger='current',
                level=logging.WARNING)
        # MMDet's loop, on an index of the checked content
        self.COCOAPI = functools.partial(CheckedCOCO, checked.coco)
        try:
            data_list = super().load_data_list()
        except (KeyError, TypeError) as err:
            raise ValueError(f'annotation file {self.ann_file} is not in COCO '
                             f'format: {err!r}') from err
        finally:
            del self.COCOAPI  # the class's again; the dict can be freed
        if self.check_files and local:
            self._check_images(data_list)
        return data_list

    def filter_data(self) -> List[dict]:
        """MMDet's filter; an empty training set is an error naming the
        annotation file (MMEngine fails later without a name)."""
        data_list = super().filter_data()
        self._report_load(data_list)
        if not data_list and not self.test_mode:
            raise ValueError(
                f'no training image left from {self.ann_file} '
                f'({len(self.data_list)} listed) after filter_cfg='
                f'{self.filter_cfg} (images without non-crowd instances '
                f'are dropped)')
        return data_list

    def _report_load(self, data_list: List[dict]) -> None:
        """Log the summary line of a full initialisation."""
        kept = {id(d) for d in data_list}
        left_out = [d for d in self.data_list if id(d) not in kept]
        instances = [i for d in data_list for i in d['instances']]
        crowd = sum(i['ignore_flag'] for i in instances)
        report = self.load_report
        report.update(
            images=len(data_list),
            instances=len(instances) - crowd,
            crowd=crowd,
            filtered_images=len(left_out),
            filtered_instances=sum(len(d['instances']) for d in left_out))
        drops = ', '.join(f'{k} {v}' for k, v in sorted(
            report['drops'].items())) or 'none'
        print_log(
            f'{type(self).__name__} {self.ann_file}: {len(data_list)} images'
            f', {report["instances"]} instances, {crowd} crowd regions; '
            f'dropped annotations: {drops}; left out by filter_cfg: '
            f'{len(left_out)} images ({report["filtered_instances"]} '
            f'instances)', logger='current', level=logging.INFO)

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
