"""Image loading that names the file when it cannot be read.

Configs name MMCV's ``LoadImageFromFile``, the type MMDetection's
``DetInferencer`` looks for (and replaces by its own loader) and after
which its corruption benchmark inserts ``Corrupt``. The CBNet datasets load
with :class:`CBNetLoadImageFromFile`, its subclass with clear errors, in
its place (:func:`with_checked_loader`), so training and testing get the
checks and MMDet's tools still recognise the pipeline.
"""
from typing import Optional, Sequence

from mmcv.transforms import LoadImageFromFile
from mmdet.registry import TRANSFORMS


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
    instead of a reshape error when its masks are decoded.

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
        if out is not None and 'height' in results and 'width' in results:
            expected = (results['height'], results['width'])
            if tuple(out['img'].shape[:2]) != expected:
                raise ValueError(
                    f'image {filename} is {out["img"].shape[0]}x'
                    f'{out["img"].shape[1]} (HxW) but its annotations say '
                    f'{expected[0]}x{expected[1]}')
        return out


#: How a pipeline config may name MMCV's loader.
MMCV_LOADER_TYPES = ('LoadImageFromFile', 'mmcv.LoadImageFromFile',
                     'mmdet.LoadImageFromFile', LoadImageFromFile)


def with_checked_loader(pipeline: Sequence) -> list:
    """Swap MMCV's ``LoadImageFromFile`` for :class:`CBNetLoadImageFromFile`.

    Args:
        pipeline (Sequence): Transform configs (dicts) or built transforms,
            as a dataset's ``pipeline`` argument takes them.

    Returns:
        list: A new list; each config whose ``type`` is MMCV's loader is a
        copy with ``type=CBNetLoadImageFromFile`` and the same arguments.
        Everything else (built transforms included) is kept as it is.
    """
    swapped = []
    for transform in pipeline:
        if isinstance(transform, dict) and \
                transform.get('type') in MMCV_LOADER_TYPES:
            transform = {**transform, 'type': CBNetLoadImageFromFile}
        swapped.append(transform)
    return swapped
