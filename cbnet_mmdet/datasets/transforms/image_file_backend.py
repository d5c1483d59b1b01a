"""A local file backend for image loading that names the file it refuses.

MMCV's ``LoadImageFromFile`` reads the bytes through MMEngine's file
backend named in its ``backend_args`` and decodes them; an empty file
fails in OpenCV's decoder (``cv2.error ... !buf.empty()``) without the
file's name. Our configs' test pipelines name this backend
(``backend_args=dict(backend='cbnet_image')``), which MMDetection's
``DetInferencer`` and ``inference_detector`` pass on to the loaders they
put in the configs' loader's place, so the check also holds there.
"""
import os.path as osp
from pathlib import Path
from typing import Union

from mmengine.fileio import LocalBackend, register_backend

#: The name configs use in ``backend_args``.
BACKEND_NAME = 'cbnet_image'
#: ``backend_args`` of our configs' image loaders.
IMAGE_BACKEND_ARGS = dict(backend=BACKEND_NAME)


@register_backend(BACKEND_NAME)
class CBNetImageFileBackend(LocalBackend):
    """MMEngine's ``LocalBackend`` that refuses a missing or empty file
    with an error naming it."""

    def get(self, filepath: Union[str, Path]) -> bytes:
        """The file's bytes.

        Raises:
            FileNotFoundError: no such file.
            ValueError: the file is empty.
        """
        if not osp.isfile(filepath):
            raise FileNotFoundError(f'image not found: {filepath}')
        data = super().get(filepath)
        if not data:
            raise ValueError(f'image file {filepath} is empty (0 bytes)')
        return data
