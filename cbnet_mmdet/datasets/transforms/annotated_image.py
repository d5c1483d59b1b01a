"""One rule for an image that has annotations, in training and testing.

A dataset's data info gives the image's ``height`` and ``width`` as its
annotation file says (VOC's ``<size>``, COCO's ``images`` entry); the
loaders check the decoded image against them, so boxes are never scored
or learnt on pixels they were not drawn on (an XML of a half-size copy).
An EXIF orientation other than 1 ("upright"; 0, which is no valid value,
decoders read as 1 too) is refused: OpenCV's default
decoding rotates such a JPEG, and whether its boxes were drawn on the
stored or on the rotated pixels is not in the file (a 180-degree turn
keeps the size, so the size check alone cannot see it). Inference on
photos without annotations (``DetInferencer``) is not concerned: there is
no ``height``/``width`` in its data, and rotating a phone photo upright
is what a user wants.

Used by :class:`.CBNetLoadImageFromFile` (training pipelines) and
:class:`.CBNetCheckImage` (test pipelines, after MMCV's loader).
"""
import os.path as osp
from typing import Optional

import numpy as np

#: The EXIF tag of the orientation.
ORIENTATION_TAG = 0x0112
#: What each orientation value does to the stored pixels.
ORIENTATIONS = {
    2: 'mirrored', 3: 'rotated 180 degrees', 4: 'mirrored vertically',
    5: 'mirrored and rotated 90 degrees', 6: 'rotated 90 degrees',
    7: 'mirrored and rotated 270 degrees', 8: 'rotated 270 degrees'
}


def exif_orientation(path: str) -> Optional[int]:
    """The EXIF orientation of an image file (None: no such tag, not a
    local file, or not an image PIL can open). Reads the header only."""
    if not isinstance(path, str) or not osp.isfile(path):
        return None
    from PIL import Image, UnidentifiedImageError
    try:
        with Image.open(path) as img:
            value = img.getexif().get(ORIENTATION_TAG)
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError):
        return None  # the decoder's own check names a broken file
    return int(value) if value is not None else None


def check_annotated_image(img: np.ndarray, results: dict,
                          allow_orientation: bool = False) -> None:
    """Raise ``ValueError`` naming the file when an annotated image does
    not fit its annotations.

    Args:
        img (np.ndarray): The decoded image.
        results (dict): The pipeline's dict: ``img_path`` and, for an image
            of a dataset, ``height`` and ``width`` (nothing is checked
            without them).
        allow_orientation (bool): Accept an EXIF orientation (the loader
            reads the stored pixels, e.g. MMCV's ``color_type=
            'color_ignore_orientation'``, and the annotations were drawn
            on them).
    """
    if 'height' not in results or 'width' not in results:
        return
    path = results.get('img_path')
    if not allow_orientation:
        value = exif_orientation(path)
        if value not in (None, 0, 1):  # 0: invalid, read as upright
            raise ValueError(
                f'image {path} carries EXIF orientation {value} (its pixels '
                f'are stored {ORIENTATIONS.get(value, "turned")}): the '
                f'decoder turns it upright, and its annotations may have '
                f'been drawn on the stored pixels; write the image upright '
                f'without the tag (PIL.ImageOps.exif_transpose) and check '
                f'its boxes, or, if they were drawn on the stored pixels, '
                f"load with color_type='color_ignore_orientation'")
    expected = (results['height'], results['width'])
    if tuple(img.shape[:2]) != tuple(expected):
        raise ValueError(
            f'image {path} is {img.shape[0]}x{img.shape[1]} (HxW) but its '
            f'annotations say {expected[0]}x{expected[1]}')
