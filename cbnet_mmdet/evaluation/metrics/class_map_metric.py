"""Score a model trained on one label set (COCO) on a dataset with
another (the project's 8 Cityscapes classes, VOC's 20): zero-shot."""
from typing import Dict, Optional, Sequence, Union

import torch
from mmdet.registry import METRICS
from mmengine.evaluator import BaseMetric
from mmengine.logging import MMLogger
from mmengine.structures import BaseDataElement

from cbnet_mmdet.utils.class_map import (describe_map, label_targets,
                                         resolve_classes)


@METRICS.register_module()
class CBNetClassMapMetric(BaseMetric):
    """Any metric, on predictions whose labels are mapped from the model's
    classes to the dataset's first.

    A COCO detector tested on a dataset of other classes predicts COCO
    labels: each prediction of source class ``s`` is scored as every
    dataset class that ``s`` stands for (:func:`cbnet_mmdet.utils
    .class_map.class_sources`: the same name, else
    :data:`~cbnet_mmdet.utils.class_map.CLASS_ALIASES`, e.g. ``rider`` from
    ``person``), and a prediction of a class that stands for none
    (COCO's ``dog``) is dropped. The wrapped metric then sees predictions
    in the dataset's labels, as if the model had been trained on them; the
    model, its checkpoint and the dataset stay as they are, so
    ``tools/test.py CONFIG COCO_CHECKPOINT`` is a zero-shot evaluation::

        test_evaluator = dict(
            type='CBNetClassMapMetric', source_classes='coco',
            metric=dict(type='CocoMetric', metric='bbox'))

    The map is logged once per dataset; a dataset class that no source
    class stands for is named in a warning (its AP is 0 where it has
    ground truth).

    Args:
        metric (dict): The wrapped metric's config (``CocoMetric``,
            ``CBNetInstanceMIoUMetric``...).
        source_classes (str | Sequence[str]): The model's class names in
            label order, or ``'coco'`` (MMDet's 80).
        aliases (dict, optional): Dataset class -> source class for names
            that differ; default :data:`~cbnet_mmdet.utils.class_map
            .CLASS_ALIASES`.
        collect_device (str): Unused (the wrapped metric collects).
        prefix (str, optional): Unused (the wrapped metric's keys).
    """

    def __init__(self,
                 metric: dict,
                 source_classes: Union[str, Sequence[str]] = 'coco',
                 aliases: Optional[Dict[str, str]] = None,
                 collect_device: str = 'cpu',
                 prefix: Optional[str] = None) -> None:
        super().__init__(collect_device=collect_device, prefix=prefix)
        if not isinstance(metric, dict) or 'type' not in metric:
            raise TypeError('CBNetClassMapMetric: metric must be a metric '
                            f'config dict with a type, got {metric!r}')
        self.metric = METRICS.build(metric)
        self.source_classes = resolve_classes(source_classes)
        self.aliases = aliases
        self._table: Optional[torch.Tensor] = None

    @property
    def dataset_meta(self) -> Optional[dict]:
        return self._dataset_meta

    @dataset_meta.setter
    def dataset_meta(self, dataset_meta: dict) -> None:
        """Set the wrapped metric's too, and build the label map."""
        self._dataset_meta = dataset_meta
        self.metric.dataset_meta = dataset_meta
        target = dataset_meta.get('classes') if dataset_meta else None
        if not target:
            raise ValueError('CBNetClassMapMetric: the dataset has no '
                             "'classes' in its metainfo to map onto")
        targets = label_targets(target, self.source_classes, self.aliases)
        width = max(1, max(len(t) for t in targets))
        # table[s, k]: the k-th dataset label of source label s, -1: none
        table = torch.full((len(targets), width), -1, dtype=torch.long)
        for s, labels in enumerate(targets):
            table[s, :len(labels)] = torch.tensor(labels, dtype=torch.long)
        self._table = table
        logger = MMLogger.get_current_instance()
        logger.info(
            f'CBNetClassMapMetric: {len(self.source_classes)} model classes '
            f'scored as {len(target)} dataset classes: '
            + describe_map(target, self.source_classes, self.aliases))
        fed = {t for labels in targets for t in labels}
        unfed = [name for i, name in enumerate(target) if i not in fed]
        if unfed:
            logger.warning(
                f'CBNetClassMapMetric: no model class stands for {unfed}: '
                'they are never predicted')

    def map_instances(self, pred: dict) -> dict:
        """``pred`` (``bboxes``, ``scores``, ``labels``, optionally
        ``masks``...) with source labels replaced by dataset labels: a row
        per dataset class its label stands for, none for a label that
        stands for no class.

        Raises:
            ValueError: A label outside the model's classes.
        """
        if self._table is None:
            raise RuntimeError('CBNetClassMapMetric: dataset_meta is not '
                               'set (the evaluator sets it from the dataset)')
        labels = torch.as_tensor(pred['labels']).long()
        n = len(labels)
        if n and (labels.min() < 0 or labels.max() >= len(self._table)):
            raise ValueError(
                f'CBNetClassMapMetric: predicted label '
                f'{int(labels.max())} outside the model\'s '
                f'{len(self._table)} source classes: the model was not '
                'trained on source_classes')
        rows, new = [], []
        for k in range(self._table.shape[1]):
            mapped = self._table[labels, k] if n else labels
            keep = torch.nonzero(mapped >= 0).flatten()
            rows.append(keep)
            new.append(mapped[keep])
        rows, new = torch.cat(rows), torch.cat(new)
        out = {}
        for key, value in pred.items():
            if key == 'labels':
                out[key] = new.to(torch.as_tensor(pred['labels']).device)
            elif hasattr(value, '__len__') and len(value) == n and \
                    hasattr(value, 'shape'):
                out[key] = value[rows.to(value.device)] if isinstance(
                    value, torch.Tensor) else value[rows.numpy()]
            else:
                out[key] = value
        return out

    def process(self, data_batch, data_samples: Sequence) -> None:
        """Map every sample's ``pred_instances``, then let the wrapped
        metric process the batch."""
        mapped = []
        for sample in data_samples:
            if isinstance(sample, BaseDataElement):
                sample = sample.to_dict()
            sample = dict(sample)
            sample['pred_instances'] = self.map_instances(
                sample['pred_instances'])
            mapped.append(sample)
        self.metric.process(data_batch, mapped)

    def compute_metrics(self, results: list) -> dict:
        return self.metric.compute_metrics(results)

    def evaluate(self, size: int) -> dict:
        """The wrapped metric's ``evaluate`` (it holds the results)."""
        return self.metric.evaluate(size)
