from .cityscapes import CBNetCityscapesDataset
from .foggy_cityscapes import CBNetFoggyCityscapesDataset
from .paired_foggy_dataset import CBNetPairedFoggyDataset
from .transforms import *  # noqa: F401,F403
from .voc_fog import CBNetVOCFogDataset

__all__ = [
    'CBNetCityscapesDataset', 'CBNetFoggyCityscapesDataset',
    'CBNetPairedFoggyDataset', 'CBNetVOCFogDataset'
]
