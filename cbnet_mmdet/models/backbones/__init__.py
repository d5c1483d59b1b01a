from .cspe import ContextualPositionEncoding
from .mit import CBNetMiT
from .mit_checkpoint import convert_mit_checkpoint

__all__ = ['CBNetMiT', 'ContextualPositionEncoding', 'convert_mit_checkpoint']
