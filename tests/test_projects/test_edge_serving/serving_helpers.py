"""What the serving project's tests share.

``png_header``: a PNG whose header claims any size (the codec's and the
server's size limits).

``tiny_coco``: three photos in a COCO file (the stream builder, the
server's COCO evaluation).

``cocoeval_ap``: the reference AP of a stream of predictions,
pycocotools' COCOeval called directly.

The offload stream: clear and foggy frames (``FRAMES``) of two annotated
images (``annotations``), ``truth`` (a perfect prediction of an image),
``NONE`` (no detection) and ``write_run`` (a fake route.py run over the
frames); the ``runs`` fixture of ``conftest.py`` writes a local and a
server run and the annotation file.
"""
import copy
import json
import os
import os.path as osp
import struct
import zlib

import mmcv
import numpy as np
import pycocotools.mask as mask_utils
from pycocotools.coco import COCO
from pycocotools.cocoeval import COCOeval


def png_header(width: int, height: int) -> bytes:
    """A PNG whose header claims ``width x height`` (the pixel data is a
    few bytes: nothing that size is ever allocated)."""

    def chunk(kind, data):
        return (struct.pack('>I', len(data)) + kind + data +
                struct.pack('>I', zlib.crc32(kind + data) & 0xffffffff))

    ihdr = struct.pack('>IIBBBBB', width, height, 8, 2, 0, 0, 0)
    return (b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', ihdr) +
            chunk(b'IDAT', zlib.compress(b'\0' * 64)) + chunk(b'IEND', b''))


def tiny_coco(root):
    """Three photos in a COCO file: two cars, a person, a dog (not a
    street class: dropped)."""
    os.makedirs(osp.join(root, 'images'))
    images, anns = [], []
    objects = {1: [(3, [5, 5, 30, 20])], 2: [(1, [40, 10, 10, 30]),
                                             (3, [2, 2, 20, 10])],
               3: [(18, [10, 10, 20, 20])]}
    for i in (1, 2, 3):
        name = f'{i:012d}.jpg'
        mmcv.imwrite(np.full((60, 80, 3), 40 * i, np.uint8),
                     osp.join(root, 'images', name))
        images.append(dict(id=i, file_name=name, width=80, height=60))
        for cat, box in objects[i]:
            anns.append(dict(id=len(anns) + 1, image_id=i, category_id=cat,
                             bbox=box, area=box[2] * box[3], iscrowd=0))
    ann = osp.join(root, 'instances_val.json')
    json.dump(dict(images=images, annotations=anns, categories=[
        dict(id=1, name='person'), dict(id=3, name='car'),
        dict(id=18, name='dog')]), open(ann, 'w'))
    return ann, osp.join(root, 'images')


def cocoeval_ap(gt, preds, iou_type):
    """The reference: pycocotools' COCOeval on the same stream."""
    coco = COCO()
    coco.dataset = copy.deepcopy(gt)
    coco.createIndex()
    cat_ids = [c['id'] for c in gt['categories']]
    dets = []
    for img, pred in zip(gt['images'], preds):
        for label, score_, box, m in zip(pred['labels'], pred['scores'],
                                         pred['bboxes'], pred['masks']):
            x1, y1, x2, y2 = box
            dets.append(dict(image_id=img['id'], category_id=cat_ids[label],
                             score=score_, bbox=[x1, y1, x2 - x1, y2 - y1],
                             segmentation=m))
    if not dets:
        return 0.0
    ev = COCOeval(coco, coco.loadRes(dets), iou_type)
    ev.evaluate()
    ev.accumulate()
    ev.summarize()
    return 100 * ev.stats[0]


# -- the offload stream ----------------------------------------------------

CLASSES = ['person', 'rider', 'car', 'truck', 'bus', 'train', 'motorcycle',
           'bicycle']
H, W = 40, 60
# (image, category id, [x, y, w, h]); the categories use Cityscapes' ids
OBJECTS = [(1, 26, [5, 5, 20, 10]), (1, 24, [30, 8, 8, 20]),
           (2, 26, [10, 20, 30, 12])]


def annotations():
    images = [dict(id=i, file_name=f'city/s{i}_leftImg8bit.png', height=H,
                   width=W) for i in (1, 2)]
    anns = []
    for n, (img, cat, (x, y, w, h)) in enumerate(OBJECTS, 1):
        poly = [x, y, x + w, y, x + w, y + h, x, y + h]
        anns.append(dict(id=n, image_id=img, category_id=cat,
                         bbox=[x, y, w, h], area=w * h, iscrowd=0,
                         segmentation=[poly]))
    cats = [dict(id=i, name=c) for i, c in zip(
        (24, 25, 26, 27, 28, 31, 32, 33), CLASSES)]
    return dict(images=images, annotations=anns, categories=cats)


def truth(img, classes=CLASSES):
    """A perfect prediction of image ``img`` in pred2dict's fields."""
    labels, boxes, masks = [], [], []
    names = {24: 'person', 26: 'car'}
    for i, cat, (x, y, w, h) in OBJECTS:
        if i != img:
            continue
        m = np.zeros((H, W), np.uint8, order='F')
        m[y:y + h, x:x + w] = 1
        rle = mask_utils.encode(m)
        rle['counts'] = rle['counts'].decode()
        labels.append(classes.index(names[cat]))
        boxes.append([x, y, x + w, y + h])
        masks.append(rle)
    return dict(labels=labels, scores=[0.9] * len(labels), bboxes=boxes,
                masks=masks)


NONE = dict(labels=[], scores=[], bboxes=[], masks=[])
FRAMES = [f'{c}/s{i}_leftImg8bit{s}.png' for i in (1, 2)
          for c, s in (('clear', ''), ('fog', '_foggy_beta_0.02'))]


def write_run(folder, mode, preds, classes=CLASSES, where='server'):
    folder.mkdir()
    with open(folder / 'results.jsonl', 'w') as f:
        for frame in FRAMES:
            foggy = 'foggy' in frame
            f.write(json.dumps(dict(
                frame=frame, where=where if mode != 'local' else 'local',
                reason='', transmission=0.4 if foggy else 0.9,
                local_top_score=0.2 if foggy else 0.9,
                seconds=2.0 if mode == 'server' else 0.5,
                prediction=preds(frame))) + '\n')
    info = dict(classes=classes)
    json.dump(dict(router=dict(mode=mode), local=dict(classes=CLASSES),
                   server=None if mode == 'local' else info),
              open(folder / 'run.json', 'w'))
    return str(folder)


def img_of(frame):
    return int(frame.split('/s')[1][0])
