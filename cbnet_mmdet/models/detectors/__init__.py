from .dehaze_data_preprocessor import CBNetDehazeDataPreprocessor
from .distiller import CBNetDistiller

__all__ = ['CBNetDehazeDataPreprocessor', 'CBNetDistiller']
