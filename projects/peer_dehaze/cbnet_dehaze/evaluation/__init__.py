from .metrics import CBNetDehazeMetric

__all__ = ['CBNetDehazeMetric']
