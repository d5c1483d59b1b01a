"""Write small PASCAL VOC folders (tests, examples of the real-fog
dataset :class:`cbnet_mmdet.datasets.CBNetVOCFogDataset`)."""
import os
import os.path as osp
from typing import Dict, List, Optional, Sequence, Tuple

import cv2
import numpy as np

#: One object: (name, (xmin, ymin, xmax, ymax)) or with a third item, the
#: ``difficult`` flag.
VOCObject = Tuple


def voc_xml(filename: str, size: Optional[Tuple[int, int]],
            objects: Sequence[VOCObject]) -> str:
    """A VOC ``<annotation>`` document.

    Args:
        filename (str): The image's file name.
        size (tuple[int, int], optional): (width, height); None writes no
            ``<size>``.
        objects (Sequence): ``(name, (xmin, ymin, xmax, ymax)[,
            difficult])`` per object.

    Returns:
        str: The XML text.
    """
    lines = ['<annotation>', '  <folder>JPEGImages</folder>',
             f'  <filename>{filename}</filename>']
    if size is not None:
        lines += ['  <size>', f'    <width>{size[0]}</width>',
                  f'    <height>{size[1]}</height>', '    <depth>3</depth>',
                  '  </size>']
    for obj in objects:
        name, box = obj[0], obj[1]
        difficult = int(obj[2]) if len(obj) > 2 else 0
        lines += ['  <object>', f'    <name>{name}</name>',
                  f'    <difficult>{difficult}</difficult>', '    <bndbox>']
        lines += [f'      <{k}>{v}</{k}>'
                  for k, v in zip(('xmin', 'ymin', 'xmax', 'ymax'), box)]
        lines += ['    </bndbox>', '  </object>']
    lines.append('</annotation>')
    return '\n'.join(lines) + '\n'


def write_voc_folder(root: str, images: Dict[str, Sequence[VOCObject]],
                     size: Tuple[int, int] = (160, 96),
                     seed: int = 0) -> List[str]:
    """A VOC folder: ``Annotations/{id}.xml`` and ``JPEGImages/{id}.jpg``.

    Each image is grey noise with every object's box painted a flat
    colour per class name (so a detector can learn them).

    Args:
        root (str): Folder to write.
        images (dict): Image id -> objects (see :func:`voc_xml`).
        size (tuple[int, int]): (width, height) of every image.
        seed (int): Seed of the noise.

    Returns:
        list[str]: The image ids, sorted.
    """
    rng = np.random.default_rng(seed)
    for sub in ('Annotations', 'JPEGImages'):
        os.makedirs(osp.join(root, sub), exist_ok=True)
    colours = {}
    for img_id, objects in images.items():
        width, height = size
        img = rng.integers(90, 140, (height, width, 3), dtype=np.uint8)
        for obj in objects:
            colour = colours.setdefault(
                obj[0], tuple(int(c) for c in rng.integers(0, 256, 3)))
            x1, y1, x2, y2 = (int(round(v)) for v in obj[1])
            img[max(y1, 0):y2, max(x1, 0):x2] = colour
        cv2.imwrite(osp.join(root, 'JPEGImages', f'{img_id}.jpg'), img)
        with open(osp.join(root, 'Annotations', f'{img_id}.xml'), 'w') as f:
            f.write(voc_xml(f'{img_id}.jpg', size, objects))
    return sorted(images)


def tiny_fog_folder(root: str, num_images: int = 10,
                    size: Tuple[int, int] = (160, 96),
                    seed: int = 0) -> List[str]:
    """A tiny VOC set with DAWN's class names: cars, persons, a motorbike
    (VOC's name), one image without objects.

    Returns:
        list[str]: The image ids, sorted.
    """
    rng = np.random.default_rng(seed)
    width, height = size
    images = {}
    for k in range(num_images):
        objects = []
        if k != num_images - 1:  # the last one has no object
            for name in ('car', 'person', 'car', 'motorbike')[:2 + k % 3]:
                w = int(rng.integers(width // 6, width // 3))
                h = int(rng.integers(height // 5, height // 2))
                x = int(rng.integers(0, width - w))
                y = int(rng.integers(0, height - h))
                objects.append((name, (x, y, x + w, y + h)))
        images[f'fog-{k:03d}'] = objects
    return write_voc_folder(root, images, size, seed)
