from .dehaze_metric import CBNetDehazeMetric

__all__ = ['CBNetDehazeMetric']
