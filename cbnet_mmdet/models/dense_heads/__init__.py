from .cbnet_cascade_rpn_head import CBNetCascadeRPNHead

__all__ = ['CBNetCascadeRPNHead']
