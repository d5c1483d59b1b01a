from .boundary_aware_loss import CBNetBoundaryAwareLoss
from .distill_loss import CBNetDistillLoss

__all__ = ['CBNetDistillLoss', 'CBNetBoundaryAwareLoss']
