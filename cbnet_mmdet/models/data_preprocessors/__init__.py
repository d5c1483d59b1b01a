from .paired_data_preprocessor import CBNetPairedDataPreprocessor

__all__ = ['CBNetPairedDataPreprocessor']
