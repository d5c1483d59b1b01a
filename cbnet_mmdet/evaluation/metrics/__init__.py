from .class_map_metric import CBNetClassMapMetric
from .instance_miou_metric import CBNetInstanceMIoUMetric

__all__ = ['CBNetClassMapMetric', 'CBNetInstanceMIoUMetric']
