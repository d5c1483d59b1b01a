from .hooks import (CBNetCheckpointReportHook, CBNetNonFiniteLossHook,
                    CBNetRNGStateHook, CBNetTeacherEMAHook)

__all__ = [
    'CBNetTeacherEMAHook', 'CBNetNonFiniteLossHook', 'CBNetRNGStateHook',
    'CBNetCheckpointReportHook'
]
