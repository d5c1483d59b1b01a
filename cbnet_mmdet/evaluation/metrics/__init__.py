from .instance_miou_metric import CBNetInstanceMIoUMetric

__all__ = ['CBNetInstanceMIoUMetric']
