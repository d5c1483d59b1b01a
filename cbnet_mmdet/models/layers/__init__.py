from .cbnet_deform_conv2d import CBNetDeformConv2d, deform_conv2d
from .cbnet_mish import CBNetMish, mish

__all__ = ['CBNetDeformConv2d', 'deform_conv2d', 'CBNetMish', 'mish']
