from .metrics import (CBNetCityScapesMetric, CBNetClassMapMetric,
                      CBNetInstanceMIoUMetric)

__all__ = [
    'CBNetCityScapesMetric', 'CBNetClassMapMetric', 'CBNetInstanceMIoUMetric'
]
