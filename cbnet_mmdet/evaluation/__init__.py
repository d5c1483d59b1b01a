from .metrics import CBNetInstanceMIoUMetric

__all__ = ['CBNetInstanceMIoUMetric']
