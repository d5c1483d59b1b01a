from .distiller import CBNetDistiller
from .paired_data_preprocessor import CBNetPairedDataPreprocessor

__all__ = ['CBNetDistiller', 'CBNetPairedDataPreprocessor']
