from .hooks import (CBNetCheckpointReportHook, CBNetNonFiniteLossHook,
                    CBNetRNGStateHook, CBNetTeacherEMAHook)
from .runner import CBNetRunner

__all__ = [
    'CBNetTeacherEMAHook', 'CBNetNonFiniteLossHook', 'CBNetRNGStateHook',
    'CBNetCheckpointReportHook', 'CBNetRunner'
]
