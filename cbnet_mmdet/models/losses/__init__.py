from .boundary_aware_loss import CBNetBoundaryAwareLoss
from .distill_loss import CBNetDistillLoss
from .sigmoid_cross_entropy_loss import CBNetSigmoidCrossEntropyLoss

__all__ = [
    'CBNetDistillLoss', 'CBNetBoundaryAwareLoss',
    'CBNetSigmoidCrossEntropyLoss'
]
