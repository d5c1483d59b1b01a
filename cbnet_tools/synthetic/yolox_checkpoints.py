"""Stand-ins of the COCO YOLOX-Nano checkpoints (``fetch_pretrained.py
yolox_nano``) for runs that must not need the real weights: the tests and
the GPU script's dry run. Seeded random weights of MMDet's YOLOX-Nano,
written under the same two names as the converter writes (80 COCO
classes, and the 8-class twin whose classifier rows are COCO's of the
same names); they detect nothing real."""
import os
import os.path as osp
from typing import Dict, Optional, Tuple

import torch

#: A batch norm whose running mean the stand-in sets away from 0, so that a
#: test sees whether fine-tuning kept the statistics (CBNetNormEvalHook).
PROBE_NORM = 'backbone.stem.conv.bn.running_mean'


def tiny_yolox_nano(folder: Optional[str] = None, seed: int = 0
                    ) -> Tuple[str, str, Dict[str, torch.Tensor]]:
    """Write the two stand-in checkpoints into ``folder`` (default: the
    pretrained cache, ``$CBNET_PRETRAINED_DIR``).

    The head's classification and objectness biases are 0 instead of
    ``init_weights``' prior (a score of 1e-4), so the untrained model
    predicts boxes above MMDet's test score threshold and evaluation has
    something to score.

    Returns:
        tuple: The 80-class and the 8-class file, and the 80-class state
        dict.
    """
    from cbnet_mmdet.datasets.voc_fog import CITYSCAPES_CLASSES
    from cbnet_tools.pretrained import PRETRAINED_FILES, pretrained_dir
    from cbnet_tools.yolox_weights import (build_mmdet_yolox, map_class_rows,
                                           street_path)
    folder = folder or pretrained_dir()
    os.makedirs(folder, exist_ok=True)
    state = torch.random.fork_rng()
    with state:
        torch.manual_seed(seed)
        model = build_mmdet_yolox()
        model.init_weights()
        weights = model.state_dict()
        weights[PROBE_NORM].uniform_(-1, 1)
    for key in weights:
        if key.startswith(('bbox_head.multi_level_conv_obj.',
                           'bbox_head.multi_level_conv_cls.')) and \
                key.endswith('bias'):
            weights[key].zero_()
    coco = osp.join(folder, PRETRAINED_FILES['yolox_nano'])
    meta = dict(stand_in=True, note='seeded random weights, not COCO')
    torch.save(dict(state_dict=weights, meta=meta), coco)
    street = street_path(coco)
    torch.save(dict(state_dict=map_class_rows(weights, CITYSCAPES_CLASSES),
                    meta=meta), street)
    return coco, street, weights
