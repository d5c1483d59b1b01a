"""What the sets' end-to-end tests build on tiny data (the MobileNetV2
weights file is the ``fake_weights`` fixture of ``conftest.py``).

``fake_coco``: the tiny generated set as one COCO-format instances file
with COCO's category ids, the input of
``tools/dataset_converters/coco_street.py``.

``save_untrained_dehazer``: an initialised demo dehazer saved where the
realfog configs load it.
"""
import json
import os
import os.path as osp

import torch
from mmdet.registry import MODELS
from mmengine.config import Config

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))

#: The project's class -> a COCO category (id, name); rider, which COCO
#: lacks, becomes a class the converter drops.
TO_COCO = {'person': (1, 'person'), 'bicycle': (2, 'bicycle'),
           'car': (3, 'car'), 'motorcycle': (4, 'motorcycle'),
           'bus': (6, 'bus'), 'train': (7, 'train'), 'truck': (8, 'truck'),
           'rider': (41, 'skateboard')}


def fake_coco(cityscapes_like_root, out):
    """The tiny generated set's train + val as one COCO instances file
    with COCO's category ids and names (photos of ``leftImg8bit``)."""
    images, anns = [], []
    for split in ('train', 'val'):
        with open(osp.join(cityscapes_like_root, 'annotations',
                           f'instancesonly_filtered_gtFine_{split}.json')) \
                as f:
            coco = json.load(f)
        names = {c['id']: c['name'] for c in coco['categories']}
        offset = 1000 * len(images) + 1000
        for img in coco['images']:
            img = dict(img, id=img['id'] + offset,
                       file_name=osp.join(split, img['file_name'])
                       if not img['file_name'].startswith(split) else
                       img['file_name'])
            images.append(img)
        for ann in coco['annotations']:
            anns.append(dict(ann, id=ann['id'] + offset,
                             image_id=ann['image_id'] + offset,
                             category_id=TO_COCO[
                                 names[ann['category_id']]][0]))
    os.makedirs(osp.join(out, 'annotations'))
    os.symlink(osp.join(cityscapes_like_root, 'leftImg8bit'),
               osp.join(out, 'images'))
    with open(osp.join(out, 'annotations', 'instances.json'), 'w') as f:
        json.dump(dict(images=images, annotations=anns, categories=[
            dict(id=i, name=n, supercategory='x')
            for i, n in sorted(TO_COCO.values())]), f)
    return images, anns


def save_untrained_dehazer(root):
    """An initialised demo dehazer where the realfog configs load it: their
    ``fog_dehazer_checkpoint`` (a relative path) under ``root``, the
    folder the test runs in. Returns that file."""
    import cbnet_dehaze  # noqa: F401  (registers the dehazer)
    configs = osp.join(ROOT, 'projects', 'peer_dehaze', 'configs')
    cfg = Config.fromfile(osp.join(configs, '_base_', 'attention_dehazer.py'))
    path = osp.join(str(root), Config.fromfile(osp.join(
        configs, 'realfog', '_base_', 'dehazers.py')).fog_dehazer_checkpoint)
    torch.manual_seed(0)
    dehazer = MODELS.build(cfg.dehazer)
    os.makedirs(osp.dirname(path), exist_ok=True)
    torch.save({'state_dict': dehazer.state_dict()}, path)
    return path
