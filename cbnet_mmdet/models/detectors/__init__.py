from .dehaze_data_preprocessor import CBNetDehazeDataPreprocessor
from .distiller import CBNetDistiller
from .paired_data_preprocessor import CBNetPairedDataPreprocessor

__all__ = [
    'CBNetDehazeDataPreprocessor', 'CBNetDistiller',
    'CBNetPairedDataPreprocessor'
]
