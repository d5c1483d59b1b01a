"""Dehazing modules (YOLO-Vehicle-Pro's learned one, the dark channel
prior) with a common [0, 1] RGB image-to-image interface."""
from .attention_dehazer import CBNetAttentionDehazer
from .base_dehazer import BaseDehazer
from .dark_channel_prior import CBNetDarkChannelPrior

__all__ = ['BaseDehazer', 'CBNetAttentionDehazer', 'CBNetDarkChannelPrior']
