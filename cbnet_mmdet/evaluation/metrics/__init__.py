from .cbnet_cityscapes_metric import CBNetCityScapesMetric
from .class_map_metric import CBNetClassMapMetric
from .instance_miou_metric import CBNetInstanceMIoUMetric

__all__ = [
    'CBNetCityScapesMetric', 'CBNetClassMapMetric', 'CBNetInstanceMIoUMetric'
]
