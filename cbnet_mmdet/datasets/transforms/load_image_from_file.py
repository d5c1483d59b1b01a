"""Image loading that names the file when it cannot be read.

The project's training pipelines name :class:`CBNetLoadImageFromFile`.
Its test pipelines name MMCV's ``LoadImageFromFile`` (the exact type
MMDetection's ``DetInferencer`` looks for and replaces by its own loader)
reading through the ``cbnet_image`` file backend
(:class:`CBNetImageFileBackend`), followed by ``CBNetCheckImage``. No
dataset changes the transforms its config names.
"""
from typing import Optional

from mmcv.transforms import LoadImageFromFile
from mmdet.registry import TRANSFORMS

from .annotated_image import check_annotated_image


@TRANSFORMS.register_module()
class CBNetLoadImageFromFile(LoadImageFromFile):
    """``LoadImageFromFile`` with clear errors.

    MMCV's transform raises a bare ``AssertionError`` (stripped under
    ``python -O``) or a decoder error without the path when an image is
    corrupt. This one raises ``FileNotFoundError`` for a missing image and
    ``ValueError`` for an undecodable one, both naming the file. With
    ``ignore_empty=True`` such images are skipped as in MMCV. An image
    whose size differs from the ``height``/``width`` its annotations give
    (the dataset's data info) raises ``ValueError`` naming the file,
    instead of a reshape error when its masks are decoded, and so does an
    annotated image with an EXIF orientation (:mod:`.annotated_image`:
    the same rule as the test pipelines' ``CBNetCheckImage``).

    Args:
        **kwargs: ``mmcv.transforms.LoadImageFromFile`` arguments.
    """

    def transform(self, results: dict) -> Optional[dict]:
        """Load ``results['img_path']`` into ``results['img']``
        (``uint8[H, W, 3]`` BGR by default).

        Returns:
            dict | None: ``results`` with ``img``, ``img_shape``,
            ``ori_shape``; None when skipped (``ignore_empty``).
        """
        filename = results['img_path']
        try:
            out = super().transform(results)
        except FileNotFoundError as err:
            raise FileNotFoundError(f'image not found: {filename}') from err
        except Exception as err:  # corrupt data: any decoder error
            if self.ignore_empty:
                return None
            raise ValueError(
                f'cannot decode image {filename}: {err!r}') from err
        if out is not None and out.get('img') is None:
            # MMCV's `assert img is not None` is gone under python -O
            raise ValueError(f'cannot decode image {filename}: empty or '
                             f'not an image file')
        if out is not None:
            check_annotated_image(
                out['img'], results,
                allow_orientation='ignore_orientation' in self.color_type)
        return out
