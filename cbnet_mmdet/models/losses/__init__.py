from .boundary_aware_loss import CBNetBoundaryAwareLoss
from .distill_loss import CBNetDistillLoss
from .patch_nce_loss import CBNetPatchNCELoss
from .sigmoid_cross_entropy_loss import CBNetSigmoidCrossEntropyLoss
from .ssim_loss import CBNetSSIMLoss

__all__ = [
    'CBNetDistillLoss', 'CBNetBoundaryAwareLoss', 'CBNetPatchNCELoss',
    'CBNetSigmoidCrossEntropyLoss', 'CBNetSSIMLoss'
]
