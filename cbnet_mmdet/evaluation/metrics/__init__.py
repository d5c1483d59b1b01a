from .dehaze_metric import CBNetDehazeMetric
from .instance_miou_metric import CBNetInstanceMIoUMetric

__all__ = ['CBNetDehazeMetric', 'CBNetInstanceMIoUMetric']
