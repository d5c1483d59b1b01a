"""Cityscapes scenes as (foggy, clear) pairs for CBNet-DD."""
from typing import Iterator

from mmdet.registry import DATASETS

from .cityscapes import CBNetCityscapesDataset
from .cityscapes_paths import beta_str, foggy_path

#: Transforms that change pixel values per channel group or assume 3
#: channels; on the stacked foggy+clear image they would either fail or
#: treat the two halves differently.
PHOTOMETRIC = 'is photometric'
UNSUPPORTED_TRANSFORMS = {
    **{
        name: PHOTOMETRIC
        for name in ('AutoAugment', 'AutoContrast', 'Albu', 'Brightness',
                     'Color', 'ColorJitter', 'ColorTransform', 'Contrast',
                     'Equalize', 'Invert', 'Normalize',
                     'PhotoMetricDistortion', 'Posterize', 'RandAugment',
                     'RandomGrayscale', 'Sharpness', 'Solarize',
                     'SolarizeAdd', 'YOLOXHSVRandomAug')
    },
    # mmcv.impad -> cv2.copyMakeBorder takes at most 4 channels.
    'Pad': 'pads with OpenCV, which takes at most 4 channels (pad in the '
    'data preprocessor with `pad_size_divisor` instead)',
}


def iter_transforms(transform) -> Iterator:
    """Yield a built transform and every transform nested inside it."""
    yield transform
    nested = getattr(transform, 'transforms', None)
    if isinstance(nested, (list, tuple)):  # Compose, RandomChoice
        for child in nested:
            yield from iter_transforms(child)
    elif nested is not None:  # RandomApply, KeyMapper: one Compose
        yield from iter_transforms(nested)


@DATASETS.register_module()
class CBNetPairedFoggyDataset(CBNetCityscapesDataset):
    """Cityscapes instance annotations with each image's foggy twin.

    Reads the same COCO-format annotations as
    :class:`CBNetCityscapesDataset` (clear ``leftImg8bit`` file names), with
    the same checks and error messages for malformed annotations, missing
    files (clear AND foggy images) and empty training sets, and adds
    ``foggy_img_path`` (``leftImg8bit_foggy/..._foggy_beta_{beta}.png``) to
    every data info. Use it with ``CBNetLoadPairedImageFromFile``, which
    stacks both images so that geometric transforms apply to both alike;
    photometric transforms (and ``Pad``, see ``UNSUPPORTED_TRANSFORMS``) in
    the pipeline are rejected.

    Args:
        beta (float): Fog density of Foggy Cityscapes: 0.005, 0.01 or 0.02.
            Defaults to 0.02.
        **kwargs: Forwarded to :class:`CBNetCityscapesDataset`
            (``ann_file``, ``data_root``, ``data_prefix``, ``pipeline``,
            ``check_files`` ...).
    """

    image_path_keys = ('img_path', 'foggy_img_path')

    def __init__(self, *args, beta: float = 0.02, **kwargs) -> None:
        beta_str(beta)  # raises on an unreleased beta
        self.beta = beta
        super().__init__(*args, **kwargs)
        for transform in iter_transforms(self.pipeline):
            name = type(transform).__name__
            if name in UNSUPPORTED_TRANSFORMS:
                raise ValueError(
                    f'CBNetPairedFoggyDataset: pipeline transform {name} '
                    f'{UNSUPPORTED_TRANSFORMS[name]}; it cannot be applied '
                    f'to the stacked 6-channel foggy+clear image')

    def parse_data_info(self, raw_data_info: dict) -> dict:
        """Add ``foggy_img_path`` to MMDetection's data info.

        Args:
            raw_data_info (dict): ``raw_ann_info`` and ``raw_img_info``.

        Returns:
            dict: Data info with ``img_path`` (clear) and
            ``foggy_img_path``.
        """
        data_info = super().parse_data_info(raw_data_info)
        data_info['foggy_img_path'] = foggy_path(data_info['img_path'],
                                                 self.beta)
        return data_info
