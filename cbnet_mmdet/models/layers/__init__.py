from .cbnet_deform_conv2d import CBNetDeformConv2d, deform_conv2d

__all__ = ['CBNetDeformConv2d', 'deform_conv2d']
