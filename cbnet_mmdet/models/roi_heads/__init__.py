from .cbnet_cascade_roi_head import CBNetCascadeRoIHead
from .mask_heads import CBNetBoundaryMaskHead

__all__ = ['CBNetCascadeRoIHead', 'CBNetBoundaryMaskHead']
