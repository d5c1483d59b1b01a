"""mIoU of instance predictions rendered into a semantic map (paper's mIoU).

Per image, the predicted instance masks scoring at least ``score_thr`` are
painted into one map of ``num_classes + 1`` values (0 = background, ``c +
1`` = class ``c``). Where masks overlap, ``paint_order`` decides the winner:
``'score'`` paints in ascending score so the highest-scoring instance is on
top; ``'area'`` paints in descending area so smaller instances stay visible
on top of larger ones. The ground-truth map is painted the same way from the
dataset's annotations (COCO JSON, crowd regions included as their class,
as in Cityscapes' ``labelIds``; ``ignore_crowd=True`` ignores those pixels
instead). A confusion matrix is accumulated over the split, and

    IoU_c = TP_c / (TP_c + FP_c + FN_c),   mIoU = mean over classes c

where classes absent from both ground truth and predictions over the whole
split (0 / 0) are NaN and excluded from the mean. The background row/column
is counted (a predicted car on road is a false positive of car) but the
background IoU is not part of the mean. Values are fractions in [0, 1], as
``CocoMetric`` reports AP.
"""
from typing import Dict, List, Optional, Sequence, Union

import numpy as np
import pycocotools.mask as mask_utils
import torch
from mmdet.datasets.api_wrappers import COCO
from mmdet.registry import METRICS
from mmengine.evaluator import BaseMetric
from mmengine.fileio import get_local_path
from mmengine.logging import MMLogger

#: Pixel value excluded from the confusion matrix.
IGNORE = 255


def paint_masks(masks: np.ndarray,
                values: np.ndarray,
                priority: np.ndarray,
                background: int = 0,
                keep: Optional[np.ndarray] = None) -> np.ndarray:
    """Paint instance masks into one map; the highest priority wins.

    Vectorised over instances: each mask gets its rank in ascending
    priority (1..N), one ``max`` over the stacked ``mask * rank`` finds the
    top-ranked mask of every pixel (no reordering copy of the masks; about
    0.1 s for 100 masks at 1024x2048 on one CPU core).

    Args:
        masks (np.ndarray): ``bool[N, H, W]`` instance masks.
        values (np.ndarray): ``int[N]`` value painted by each mask.
        priority (np.ndarray): ``float[N]``; on overlaps the mask with the
            larger priority wins (ties: the later one).
        background (int): Value where no mask covers the pixel.
        keep (np.ndarray, optional): ``bool[N]``; masks not kept are not
            painted (cheaper than indexing, which copies the masks).

    Returns:
        np.ndarray: ``uint8[H, W]`` painted map.
    """
    n = len(masks)
    keep = np.ones(n, bool) if keep is None else np.asarray(keep, bool)
    if not keep.any():
        return np.full(masks.shape[1:], background, np.uint8)
    # kept masks by ascending priority; among equals the later one higher
    idx = np.flatnonzero(keep)
    asc = idx[np.lexsort((idx, np.asarray(priority)[idx]))]
    dtype = np.uint8 if n < 256 else np.int32
    rank = np.zeros(n, dtype)  # 0: not painted
    rank[asc] = np.arange(1, len(asc) + 1)
    top = (masks.astype(bool, copy=False) * rank[:, None, None]).max(0)
    value_of_rank = np.concatenate([[background], np.asarray(values)[asc]])
    return value_of_rank[top].astype(np.uint8)


def confusion_matrix(gt: np.ndarray, pred: np.ndarray,
                     num_values: int) -> np.ndarray:
    """Pixel confusion matrix, rows = ground truth, columns = prediction.

    Args:
        gt (np.ndarray): ``uint8[H, W]`` ground-truth map, ``IGNORE`` pixels
            skipped.
        pred (np.ndarray): ``uint8[H, W]`` predicted map.
        num_values (int): Number of values (classes + background).

    Returns:
        np.ndarray: ``int64[num_values, num_values]`` pixel counts.
    """
    valid = gt != IGNORE
    idx = gt[valid].astype(np.int64) * num_values + pred[valid]
    return np.bincount(idx, minlength=num_values**2).reshape(
        num_values, num_values)


@METRICS.register_module()
class CBNetInstanceMIoUMetric(BaseMetric):
    """Semantic mIoU of instance-segmentation predictions.

    Add it next to ``CocoMetric`` in ``val_evaluator`` /
    ``test_evaluator``::

        val_evaluator = [
            dict(type='CocoMetric', ann_file=ANN, metric=['bbox', 'segm']),
            dict(type='CBNetInstanceMIoUMetric', ann_file=ANN,
                 score_thr=0.5, paint_order='score'),
        ]

    Reports ``cityscapes/mIoU`` and ``cityscapes/IoU_{class}``. Each
    process keeps only small confusion matrices, which MMEngine gathers
    across ranks under distributed evaluation.

    Args:
        ann_file (str, optional): COCO JSON of the evaluated split (e.g. the
            converter's ``instancesonly_filtered_gtFine_val.json``); ground
            truth is rendered from it. Without it, the data samples must
            carry the raw ``instances`` (add ``'instances'`` to
            ``PackDetInputs.meta_keys``).
        score_thr (float): Predictions scoring below are not painted.
            Default 0.5, the usual threshold for visualising masks.
        paint_order (str): ``'score'`` (highest score on top) or ``'area'``
            (smallest mask on top).
        ignore_crowd (bool): Ignore ground-truth crowd pixels instead of
            counting them as their class.
        collect_device (str): ``'cpu'`` or ``'gpu'`` for gathering results.
        prefix (str, optional): Key prefix; default ``'cityscapes'``.
        backend_args (dict, optional): File backend of ``ann_file``.
    """
    default_prefix: Optional[str] = 'cityscapes'

    def __init__(self,
                 ann_file: Optional[str] = None,
                 score_thr: float = 0.5,
                 paint_order: str = 'score',
                 ignore_crowd: bool = False,
                 collect_device: str = 'cpu',
                 prefix: Optional[str] = None,
                 backend_args: Optional[dict] = None) -> None:
        super().__init__(collect_device=collect_device, prefix=prefix)
        if paint_order not in ('score', 'area'):
            raise ValueError(f"paint_order must be 'score' or 'area', got "
                             f'{paint_order!r}')
        self.score_thr = score_thr
        self.paint_order = paint_order
        self.ignore_crowd = ignore_crowd
        self.ann_file = ann_file
        self._coco = None
        if ann_file is not None:
            with get_local_path(ann_file, backend_args=backend_args) as path:
                self._coco = COCO(path)

    @property
    def classes(self) -> Sequence[str]:
        """Class names, from the dataset's ``metainfo``."""
        if not self.dataset_meta or 'classes' not in self.dataset_meta:
            raise RuntimeError(
                f'{type(self).__name__} needs dataset_meta["classes"] (set '
                f'by the Evaluator from the dataset)')
        return self.dataset_meta['classes']

    def _gt_annotations(self, data_sample: dict) -> List[dict]:
        """Ground-truth annotations of a sample as ``(rle-able segmentation,
        label index, crowd)`` dicts."""
        img_id = data_sample['img_id']
        if self._coco is not None:
            if img_id not in self._coco.imgs:
                raise KeyError(f'image id {img_id} is not in {self.ann_file}')
            cat_ids = self._coco.get_cat_ids(cat_names=self.classes)
            cat2label = {cat: i for i, cat in enumerate(cat_ids)}
            anns = self._coco.load_anns(
                self._coco.get_ann_ids(img_ids=[img_id]))
            return [
                dict(segm=a['segmentation'], label=cat2label[a['category_id']],
                     crowd=bool(a.get('iscrowd', 0))) for a in anns
                if a['category_id'] in cat2label and a.get('segmentation')
            ]
        if 'instances' not in data_sample:
            raise KeyError(
                f'{type(self).__name__}: no ann_file and the data sample '
                f'of image {img_id} has no raw "instances" (add it to '
                f'PackDetInputs.meta_keys)')
        return [
            dict(segm=a['mask'], label=a['bbox_label'],
                 crowd=bool(a.get('ignore_flag', 0)))
            for a in data_sample['instances'] if a.get('mask')
        ]

    def gt_map(self, data_sample: dict) -> np.ndarray:
        """Ground-truth semantic map, ``uint8[H, W]`` at ``ori_shape``."""
        h, w = data_sample['ori_shape'][:2]
        anns = self._gt_annotations(data_sample)
        if not anns:
            return np.zeros((h, w), np.uint8)
        rles = []
        for a in anns:
            segm = a['segm']
            if isinstance(segm, list):  # polygons
                segm = mask_utils.merge(mask_utils.frPyObjects(segm, h, w))
            elif isinstance(segm['counts'], list):  # uncompressed RLE
                segm = mask_utils.frPyObjects(segm, h, w)
            rles.append(segm)
        masks = mask_utils.decode(rles).transpose(2, 0, 1).astype(bool)
        if masks.shape[1:] != (h, w):
            raise ValueError(
                f'ground-truth masks of image {data_sample["img_id"]} are '
                f'{masks.shape[1:]}, the image is {(h, w)}')
        labels = np.array([a['label'] + 1 for a in anns])
        crowd = np.array([a['crowd'] for a in anns])
        if self.ignore_crowd:
            labels = np.where(crowd, IGNORE, labels)
        return paint_masks(masks, labels, np.arange(len(anns), dtype=float))

    def pred_map(self, pred: dict, shape: Sequence[int]) -> np.ndarray:
        """Predicted semantic map, ``uint8[H, W]``.

        Args:
            pred (dict): ``pred_instances`` with ``masks``
                (``Tensor[N, H, W]`` bool or a list of COCO RLEs),
                ``scores`` (``Tensor[N]``) and ``labels`` (``Tensor[N]``).
            shape (Sequence[int]): ``(H, W)`` of the original image.
        """
        if 'masks' not in pred:
            raise KeyError(f'{type(self).__name__} needs predicted masks '
                           f'(an instance segmentation model)')
        scores = _numpy(pred['scores']).astype(np.float64)
        labels = _numpy(pred['labels']).astype(np.int64)
        keep = scores >= self.score_thr
        masks = pred['masks']
        if isinstance(masks, (list, tuple)):  # RLEs: decode the kept ones
            idx = np.flatnonzero(keep)
            masks = (mask_utils.decode([masks[i] for i in idx]).transpose(
                2, 0, 1) if len(idx) else np.zeros((0, *shape), np.uint8))
            scores, labels = scores[idx], labels[idx]
            keep = np.ones(len(idx), bool)
        masks = _numpy(masks)
        if masks.shape[1:] != tuple(shape):
            raise ValueError(f'predicted masks are {masks.shape[1:]}, the '
                             f'image is {tuple(shape)}: predict with '
                             f'rescale=True')
        if self.paint_order == 'score':
            priority = scores
        else:
            priority = -masks.reshape(len(masks), -1).sum(1, dtype=float)
        return paint_masks(masks, labels + 1, priority, keep=keep)

    def process(self, data_batch: dict, data_samples: Sequence[dict]) -> None:
        """Accumulate one confusion matrix per image.

        Args:
            data_batch (dict): The batch from the dataloader (unused).
            data_samples (Sequence[dict]): Outputs with ``pred_instances``,
                ``img_id`` and ``ori_shape``.
        """
        n = len(self.classes) + 1
        for sample in data_samples:
            gt = self.gt_map(sample)
            pred = self.pred_map(sample['pred_instances'], gt.shape)
            self.results.append(confusion_matrix(gt, pred, n))

    def compute_metrics(self, results: list) -> Dict[str, float]:
        """Per-class IoU and their mean from the summed confusion matrices.

        Returns:
            dict[str, float]: ``mIoU`` and ``IoU_{class}`` (fractions; NaN
            for a class absent from ground truth and predictions).
        """
        cm = np.sum(results, axis=0)
        tp = np.diag(cm)
        union = cm.sum(0) + cm.sum(1) - tp
        with np.errstate(divide='ignore', invalid='ignore'):
            iou = (tp / union)[1:]
        out = {f'IoU_{c}': round(float(v), 4)
               for c, v in zip(self.classes, iou)}
        present = ~np.isnan(iou)
        if not present.any():
            MMLogger.get_current_instance().warning(
                'mIoU: no class in ground truth or predictions: NaN')
            out['mIoU'] = float('nan')
        else:
            out['mIoU'] = round(float(iou[present].mean()), 4)
        return out


def _numpy(x: Union[torch.Tensor, np.ndarray]) -> np.ndarray:
    return x.detach().cpu().numpy() if isinstance(x, torch.Tensor) else \
        np.asarray(x)
