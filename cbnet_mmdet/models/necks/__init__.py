from .cbnet_nas_fpn import CBNetNASFPN

__all__ = ['CBNetNASFPN']
