from .cbnet_cascade_rpn_head import CBNetCascadeRPNHead
from .cbnet_stage_cascade_rpn_head import CBNetStageCascadeRPNHead

__all__ = ['CBNetCascadeRPNHead', 'CBNetStageCascadeRPNHead']
