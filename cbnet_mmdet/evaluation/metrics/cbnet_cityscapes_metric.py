"""The official Cityscapes instance AP (cityscapesScripts), for clear and
foggy images alike.

MMDetection's ``CityScapesMetric`` writes each prediction as the
benchmark's PNG masks and scores them with cityscapesScripts'
``evaluateImgLists``: the number the Cityscapes benchmark and the papers
report (COCO-style AP on Cityscapes differs from it by a lot). It finds an
image's ground truth by replacing ``leftImg8bit`` in the image's path,
which fits clear Cityscapes only: a Foggy Cityscapes image
(``leftImg8bit_foggy/val/CITY/NAME_leftImg8bit_foggy_beta_0.02.png``)
names no ground truth file, and a missing one fails deep inside
cityscapesScripts. This metric finds it from the image's name in both
cases, ``<root>/gtFine/<split>/<city>/<stem>_gtFine_instanceIds.png``
(``<stem>`` = the name up to ``_leftImg8bit``; ``seg_prefix``, when given,
replaces ``<root>/gtFine/<split>``), and refuses a missing one naming the
image and the file, before anything is scored. Its results go to a
temporary folder unless ``outfile_prefix`` is given (MMDet's deletes
``outfile_prefix/results`` first: two runs given the same one would
collide).
"""
import os.path as osp
from typing import Optional, Sequence

from mmdet.evaluation.metrics import CityScapesMetric
from mmdet.registry import METRICS

#: The part of a Cityscapes image name that ends its stem.
IMAGE_TAG = '_leftImg8bit'


def ground_truth_file(img_path: str, seg_prefix: Optional[str] = None) -> str:
    """The ``gtFine_instanceIds.png`` of a (clear or foggy) Cityscapes
    image.

    Args:
        img_path (str): ``<root>/leftImg8bit[_foggy]/<split>/<city>/
            <stem>_leftImg8bit[...].png``.
        seg_prefix (str, optional): The ``gtFine/<split>`` folder; default
            the one beside the image's ``leftImg8bit*`` folder.

    Raises:
        ValueError: the name is not a Cityscapes image name.
    """
    name = osp.basename(img_path)
    if IMAGE_TAG not in name:
        raise ValueError(f'{img_path}: not a Cityscapes image name (no '
                         f'{IMAGE_TAG!r}), so no gtFine file to score it '
                         'against')
    stem = name[:name.index(IMAGE_TAG)]
    city_dir = osp.dirname(img_path)
    city = osp.basename(city_dir)
    if seg_prefix is None:
        split_dir = osp.dirname(city_dir)
        seg_prefix = osp.join(osp.dirname(osp.dirname(split_dir)), 'gtFine',
                              osp.basename(split_dir))
    return osp.join(seg_prefix, city, f'{stem}_gtFine_instanceIds.png')


@METRICS.register_module()
class CBNetCityScapesMetric(CityScapesMetric):
    """MMDetection's ``CityScapesMetric`` (the official instance AP,
    ``cityscapes/mAP`` and ``cityscapes/AP@50``, fractions in [0, 1]) with
    the ground truth found for clear and foggy images (module docstring).

    Args:
        outfile_prefix (str, optional): Where the PNG masks and txt files
            go (``outfile_prefix/results``); default a temporary folder.
        seg_prefix (str, optional): The ``gtFine/<split>`` folder; default
            the one beside each image's ``leftImg8bit*`` folder.
        **kwargs: ``CityScapesMetric``'s other arguments.
    """

    def __init__(self,
                 outfile_prefix: Optional[str] = None,
                 seg_prefix: Optional[str] = None,
                 **kwargs) -> None:
        self.gt_prefix = seg_prefix
        # MMDet's needs a seg_prefix to score; the files are found per
        # image here
        super().__init__(
            outfile_prefix=outfile_prefix,
            seg_prefix=seg_prefix or '',
            **kwargs)

    def process(self, data_batch: dict, data_samples: Sequence[dict]) -> None:
        """MMDet's, with each image's ground truth file found and checked.

        Raises:
            FileNotFoundError: an image's ``gtFine_instanceIds.png`` is
                missing (named, with the image).
            ValueError: a prediction has no masks (a box-only model: the
                official metric scores instance masks).
        """
        files = []
        for sample in data_samples:
            if 'masks' not in sample['pred_instances']:
                raise ValueError(
                    f'{sample["img_path"]}: the prediction has no masks; '
                    'the official Cityscapes metric scores instance masks '
                    '(leave CBNetCityScapesMetric out of a box-only '
                    "config's evaluators)")
            gt = ground_truth_file(sample['img_path'], self.gt_prefix)
            if not osp.isfile(gt):
                raise FileNotFoundError(
                    f'{sample["img_path"]}: its ground truth {gt} is '
                    'missing (the official Cityscapes metric reads '
                    "gtFine's *_instanceIds.png; the generated stand-in "
                    'writes them too)')
            files.append(gt)
        start = len(self.results)
        super().process(data_batch, data_samples)
        for (gt, _), path in zip(self.results[start:], files):
            gt['file_name'] = path
