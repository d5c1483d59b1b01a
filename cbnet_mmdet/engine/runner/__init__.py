from .cbnet_runner import CBNetRunner

__all__ = ['CBNetRunner']
