"""Load a foggy image and its clear twin as one 6-channel image."""
from typing import Optional

import numpy as np
from mmdet.registry import TRANSFORMS

from .load_image_from_file import CBNetLoadImageFromFile


@TRANSFORMS.register_module()
class CBNetLoadPairedImageFromFile(CBNetLoadImageFromFile):
    """Load ``foggy_img_path`` and ``img_path`` stacked along channels.

    The result ``img`` is ``uint8[H, W, 6]``: the foggy image in channels
    0-2, the clear image of the same scene in channels 3-5 (both in
    ``channel_order`` of mmcv, BGR by default). Every later geometric
    transform (``Resize``, ``RandomCrop``, ``RandomFlip``, ``Pad`` ...)
    therefore transforms both with the same parameters, which is how the
    student and the teacher of ``CBNetDistiller`` get the same crop.
    Photometric transforms must not follow (they would mix or reject the 6
    channels); ``CBNetPairedFoggyDataset`` refuses them.

    An image whose size differs from the ``height``/``width`` its
    annotations give (the dataset's data info), or a foggy image of another
    size than its clear twin, raises ``ValueError`` naming the files; a
    missing, empty, truncated or undecodable image (foggy or clear) raises
    the errors of :class:`CBNetLoadImageFromFile` naming it.

    Required keys: ``img_path`` (clear), ``foggy_img_path``.
    Added keys: ``img``, ``img_shape``, ``ori_shape``.

    Args:
        **kwargs: Forwarded to mmcv's ``LoadImageFromFile``;
            ``color_type`` must stay ``'color'`` (3 channels each).
    """

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        if self.color_type != 'color':
            raise ValueError(
                f'CBNetLoadPairedImageFromFile: color_type must be '
                f"'color' (two 3-channel images), got {self.color_type!r}")

    def transform(self, results: dict) -> Optional[dict]:
        """Load both images and stack them.

        Args:
            results (dict): With ``img_path`` and ``foggy_img_path``.

        Returns:
            dict or None: ``results`` with ``img`` uint8[H, W, 6] (float32
            with ``to_float32``); None if a file is empty and
            ``ignore_empty``.
        """
        if 'foggy_img_path' not in results:
            raise KeyError(
                'CBNetLoadPairedImageFromFile: `foggy_img_path` missing from '
                f"the data info of {results.get('img_path')}; use "
                'CBNetPairedFoggyDataset')
        foggy = super().transform(dict(img_path=results['foggy_img_path']))
        clear = super().transform(dict(img_path=results['img_path']))
        if foggy is None or clear is None:
            return None
        if foggy['img'].shape != clear['img'].shape:
            raise ValueError(
                f'CBNetLoadPairedImageFromFile: foggy image '
                f"{results['foggy_img_path']} {foggy['img'].shape} and "
                f"clear image {results['img_path']} {clear['img'].shape} "
                'differ in size')
        if 'height' in results and 'width' in results:
            expected = (results['height'], results['width'])
            if tuple(clear['img'].shape[:2]) != expected:
                raise ValueError(
                    f"CBNetLoadPairedImageFromFile: image "
                    f"{results['img_path']} is {clear['img'].shape[0]}x"
                    f"{clear['img'].shape[1]} (HxW) but its annotations say "
                    f'{expected[0]}x{expected[1]}')
        img = np.concatenate([foggy['img'], clear['img']], axis=2)
        results['img'] = img
        results['img_shape'] = img.shape[:2]
        results['ori_shape'] = img.shape[:2]
        return results
