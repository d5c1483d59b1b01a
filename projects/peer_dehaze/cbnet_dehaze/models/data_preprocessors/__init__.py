from .dehaze_data_preprocessor import CBNetDehazeDataPreprocessor

__all__ = ['CBNetDehazeDataPreprocessor']
