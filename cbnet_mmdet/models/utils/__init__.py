from .memory_format import use_channels_last

__all__ = ['use_channels_last']
