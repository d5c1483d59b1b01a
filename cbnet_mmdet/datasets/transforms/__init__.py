from .add_fog import CBNetAddFog
from .add_foggy_twin import CBNetAddFoggyTwin
from .check_image import CBNetCheckImage
from .image_file_backend import CBNetImageFileBackend
from .load_image_from_file import CBNetLoadImageFromFile
from .paired_loading import CBNetLoadPairedImageFromFile

__all__ = [
    'CBNetLoadImageFromFile', 'CBNetLoadPairedImageFromFile',
    'CBNetCheckImage', 'CBNetImageFileBackend', 'CBNetAddFog',
    'CBNetAddFoggyTwin'
]
