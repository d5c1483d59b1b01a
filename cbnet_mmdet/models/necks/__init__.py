from .cbnet_extra_levels import CBNetExtraLevels
from .cbnet_nas_fpn import CBNetNASFPN

__all__ = ['CBNetExtraLevels', 'CBNetNASFPN']
