"""MMDet's ``DetInferencer`` behind one batched ``predict`` call.

The server and the edge router both run a detector through this class, so
there is one preprocessing path: the config's test pipeline, as
``DetInferencer`` builds it (``LoadImageFromFile`` swapped for the
ndarray loader, ``LoadAnnotations`` dropped), and its ``pred2dict`` output
(``labels``, ``scores``, ``bboxes`` in x1y1x2y2 pixels of the input image,
``masks`` as pycocotools RLE with ``counts`` as str).
"""
import logging
import os.path as osp
from typing import Dict, List, Optional

import numpy as np
from mmdet.apis import DetInferencer
from mmdet.registry import DATASETS
from mmengine.logging import MMLogger

import cbnet_mmdet  # noqa: F401  (registers the CBNet modules)


#: What MMEngine logs when MMDetection's inferencer builds its collate
#: function, with any MMDet config (its own demos too): mmdet has no
#: "function" registry, so MMEngine's own is searched and gives
#: ``pseudo_collate``, which is what the inferencer wants. Harmless, and
#: in a server's log it reads like a failure; dropped while the server
#: builds its inferencer, nothing else is.
COLLATE_NOTICE = ('Failed to search registry with scope "mmdet" in the '
                  '"function" registry tree')


class _DropCollateNotice(logging.Filter):
    """Drops :data:`COLLATE_NOTICE`, passes every other record."""

    def filter(self, record: logging.LogRecord) -> bool:
        return COLLATE_NOTICE not in record.getMessage()


class Predictor:
    """A detector from a config and (optionally) a checkpoint.

    Args:
        config (str): config file.
        checkpoint (str, optional): checkpoint file; None runs the
            model's own initialisation (random weights), said in
            :meth:`info`.
        device (str): torch device. Defaults to 'cpu'.
    """

    def __init__(self,
                 config: str,
                 checkpoint: Optional[str] = None,
                 device: str = 'cpu') -> None:
        if not osp.isfile(config):
            raise FileNotFoundError(f'config file {config} not found')
        if checkpoint is not None and not osp.isfile(checkpoint):
            raise FileNotFoundError(f'checkpoint file {checkpoint} not found')
        self.config = config
        self.checkpoint = checkpoint
        self.device = device
        logger = MMLogger.get_current_instance()
        notice = _DropCollateNotice()
        logger.addFilter(notice)
        try:
            self.inferencer = DetInferencer(
                model=config, weights=checkpoint, device=device,
                show_progress=False)
        finally:
            logger.removeFilter(notice)
        if checkpoint is None:
            # DetInferencer falls back to COCO's classes without weights;
            # the config's test dataset names the classes instead
            dataset = self.inferencer.cfg.test_dataloader.dataset
            cls = DATASETS.get(dataset.get('type'))
            if cls is not None and hasattr(cls, 'METAINFO'):
                self.inferencer.model.dataset_meta = dict(cls.METAINFO)

    def predict(self, images: List[np.ndarray]) -> List[Dict]:
        """Detect on BGR uint8 images; one ``pred2dict`` per image."""
        if not images:
            return []
        out = self.inferencer(
            list(images), batch_size=len(images), return_vis=False,
            no_save_vis=True, no_save_pred=True, print_result=False)
        return out['predictions']

    def info(self) -> Dict:
        """What the server answers on /info."""
        meta = self.inferencer.model.dataset_meta or {}
        return dict(
            config=osp.basename(self.config),
            checkpoint=(osp.basename(self.checkpoint)
                        if self.checkpoint else None),
            weights='checkpoint' if self.checkpoint else 'random init',
            device=self.device,
            classes=list(meta.get('classes', ())),
            model=type(self.inferencer.model).__name__)
