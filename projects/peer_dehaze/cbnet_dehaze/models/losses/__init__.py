from .patch_nce_loss import CBNetPatchNCELoss
from .ssim_loss import CBNetSSIMLoss

__all__ = ['CBNetPatchNCELoss', 'CBNetSSIMLoss']
