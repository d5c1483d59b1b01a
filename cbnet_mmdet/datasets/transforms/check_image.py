"""Refuse, naming the input, an image the model cannot take."""
from typing import Optional

import numpy as np
from mmcv.transforms import BaseTransform
from mmdet.registry import TRANSFORMS

from .annotated_image import check_annotated_image


@TRANSFORMS.register_module()
class CBNetCheckImage(BaseTransform):
    """Check ``results['img']`` right after the image is loaded.

    MMDetection's inference API (``DetInferencer``, ``inference_detector``)
    replaces the configs' ``LoadImageFromFile`` with its own loaders, which
    take file paths and arrays as they come: a 2-D (grey) array passes
    them and fails later with an ``IndexError`` inside MMEngine's data
    preprocessor. Placed after the loader in our test pipelines, this
    transform raises a ``ValueError`` naming the file (or the array's
    shape) and the fix instead. It changes nothing.

    An image of a dataset (its data info gives ``height`` and ``width``,
    as in ``tools/test.py`` and every evaluation) is checked as training
    checks it (:mod:`.annotated_image`): its size must be the one its
    annotations give, and an EXIF orientation is refused, naming the
    file, so that no AP is computed against boxes on other pixels.

    Args:
        channels (int): Channels the model takes. Defaults to 3 (BGR).
        allow_exif_orientation (bool): Accept annotated images with an
            EXIF orientation (when the loader reads the stored pixels with
            ``color_type='color_ignore_orientation'`` and the annotations
            were drawn on them). Defaults to False.
    """

    def __init__(self, channels: int = 3,
                 allow_exif_orientation: bool = False) -> None:
        self.channels = channels
        self.allow_exif_orientation = allow_exif_orientation

    def transform(self, results: dict) -> Optional[dict]:
        """Return ``results`` unchanged when its image fits.

        Raises:
            ValueError: no image, an empty one, or not ``H x W x
                channels``.
        """
        img = results.get('img')
        name = results.get('img_path') or 'the input array'
        if not isinstance(img, np.ndarray):
            raise ValueError(f'no image was loaded from {name} (got '
                             f'{type(img).__name__})')
        if img.ndim != 3 or img.shape[2] != self.channels:
            raise ValueError(
                f'{name}: the image has shape {tuple(img.shape)} but the '
                f'model takes H x W x {self.channels} images (BGR, as '
                f'cv2.imread / mmcv.imread return them); convert a grey '
                f'H x W array with cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) '
                f'and an RGBA one with cv2.COLOR_RGBA2BGR')
        if img.shape[0] == 0 or img.shape[1] == 0:
            raise ValueError(f'{name}: the image is empty (shape '
                             f'{tuple(img.shape)})')
        check_annotated_image(img, results, self.allow_exif_orientation)
        return results

    def __repr__(self) -> str:
        return (f'{type(self).__name__}(channels={self.channels}, '
                f'allow_exif_orientation={self.allow_exif_orientation})')
