from .checkpoint_report_hook import CBNetCheckpointReportHook
from .non_finite_loss_hook import CBNetNonFiniteLossHook
from .norm_eval_hook import CBNetNormEvalHook
from .rng_state_hook import CBNetRNGStateHook
from .teacher_ema_hook import CBNetTeacherEMAHook
from .weights_only_checkpoint_hook import CBNetWeightsOnlyCheckpointHook

__all__ = [
    'CBNetTeacherEMAHook', 'CBNetNonFiniteLossHook', 'CBNetRNGStateHook',
    'CBNetCheckpointReportHook', 'CBNetWeightsOnlyCheckpointHook',
    'CBNetNormEvalHook'
]
