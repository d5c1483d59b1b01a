from .cbnet_boundary_mask_head import CBNetBoundaryMaskHead

__all__ = ['CBNetBoundaryMaskHead']
