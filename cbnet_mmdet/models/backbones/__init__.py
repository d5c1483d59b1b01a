from .cspe import ContextualPositionEncoding
from .efficientnet_lite import CBNetEfficientNetLite
from .mit import CBNetMiT
from .mit_checkpoint import convert_mit_checkpoint

__all__ = [
    'CBNetEfficientNetLite', 'CBNetMiT', 'ContextualPositionEncoding',
    'convert_mit_checkpoint'
]
