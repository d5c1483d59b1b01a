from .dark_channel import DarkChannelPrior
from .memory_format import use_channels_last

__all__ = ['DarkChannelPrior', 'use_channels_last']
