"""A generated stand-in for Cityscapes / Foggy Cityscapes (same layout)."""
from .cityscapes_like import (add_fog, generate_cityscapes_like, image_stem,
                              load_record, record_differences,
                              tiny_converted)
from .scene import INSTANCE_CLASSES

__all__ = [
    'generate_cityscapes_like', 'add_fog', 'image_stem', 'load_record',
    'record_differences', 'tiny_converted',
    'INSTANCE_CLASSES'
]
