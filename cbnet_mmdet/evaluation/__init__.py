from .metrics import CBNetClassMapMetric, CBNetInstanceMIoUMetric

__all__ = ['CBNetClassMapMetric', 'CBNetInstanceMIoUMetric']
