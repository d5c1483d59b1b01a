"""Dehazing modules (YOLO-Vehicle-Pro's learned one, the dark channel
prior) with a common [0, 1] RGB image-to-image interface."""
from .attention_dehazer import CBNetAttentionDehazer
from .base_dehazer import BaseDehazer
from .dark_channel_prior import CBNetDarkChannelPrior
from .dehaze_model import CBNetDehazeModel
from .dehazer_checkpoint import load_dehazer_checkpoint
from .patch_discriminator import CBNetPatchDiscriminator

__all__ = [
    'BaseDehazer', 'CBNetAttentionDehazer', 'CBNetDarkChannelPrior',
    'CBNetDehazeModel', 'CBNetPatchDiscriminator', 'load_dehazer_checkpoint'
]
