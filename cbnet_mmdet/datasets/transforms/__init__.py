from .load_image_from_file import CBNetLoadImageFromFile
from .paired_loading import CBNetLoadPairedImageFromFile

__all__ = ['CBNetLoadImageFromFile', 'CBNetLoadPairedImageFromFile']
