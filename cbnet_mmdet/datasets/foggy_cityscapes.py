"""Foggy Cityscapes: Cityscapes annotations on the foggy images."""
from typing import List, Union

from mmdet.registry import DATASETS
from .cityscapes import CBNetCityscapesDataset
from .cityscapes_paths import beta_str, foggy_path


@DATASETS.register_module()
class CBNetFoggyCityscapesDataset(CBNetCityscapesDataset):
    """Foggy Cityscapes with the fog density chosen in the config.

    Reads the same COCO JSON as :class:`CBNetCityscapesDataset` (Foggy
    Cityscapes shares Cityscapes' annotations) and swaps every image for
    its foggy twin
    ``leftImg8bit_foggy/{split}/{city}/{stem}_leftImg8bit_foggy_beta_{beta}.png``
    (see :func:`~cbnet_mmdet.datasets.cityscapes_paths.foggy_path`); the
    clear path stays in ``clear_img_path``. Keep ``data_prefix.img`` at
    ``'leftImg8bit/{split}/'``. Missing foggy images raise
    ``FileNotFoundError`` naming them.

    Args:
        beta (float): Fog attenuation coefficient, 1/m: 0.005, 0.01 or
            0.02 (visibility 600, 300, 150 m). Default 0.02, the common
            benchmark; the paper's figures use 0.01.
        **kwargs: :class:`CBNetCityscapesDataset` arguments.
    """

    def __init__(self, *args, beta: float = 0.02, **kwargs) -> None:
        beta_str(beta)  # validates
        self.beta = beta
        super().__init__(*args, **kwargs)

    def parse_data_info(self, raw_data_info: dict) -> Union[dict, List[dict]]:
        """Parse like ``CocoDataset`` and point ``img_path`` to the foggy
        image."""
        info = super().parse_data_info(raw_data_info)
        info['clear_img_path'] = info['img_path']
        info['img_path'] = foggy_path(info['img_path'], self.beta)
        return info
