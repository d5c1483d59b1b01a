"""HTTP request body -> BGR image, with the server's input checks."""
import io
from typing import Optional

import mmcv
import numpy as np
from PIL import Image

#: Largest accepted image, pixels (Cityscapes' 2048x1024 is 2.1 M).
DEFAULT_MAX_PIXELS = 4096 * 4096
#: Largest accepted body, bytes.
DEFAULT_MAX_BYTES = 64 * 1024 * 1024
#: Content types the /predict endpoint accepts.
ACCEPTED_TYPES = ('image/', 'application/octet-stream')


class BadImage(ValueError):
    """An input the server refuses, with the HTTP status to answer."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


def decode_image(body: bytes,
                 content_type: Optional[str],
                 max_pixels: int = DEFAULT_MAX_PIXELS,
                 max_bytes: int = DEFAULT_MAX_BYTES) -> np.ndarray:
    """Check and decode an encoded image (PNG, JPEG, ...) to BGR uint8.

    The size is read from the header before anything is decoded, so a
    huge image is refused without allocating it.

    Raises:
        BadImage: 415 for a content type other than ``image/*`` or
            ``application/octet-stream``; 400 for an empty body or bytes
            that are no image; 413 for a body over ``max_bytes`` or an
            image over ``max_pixels``.
    """
    ctype = (content_type or '').split(';')[0].strip().lower()
    if not ctype.startswith(ACCEPTED_TYPES):
        raise BadImage(
            415, f'unsupported Content-Type {content_type!r}: send the '
            'encoded image bytes as image/png, image/jpeg or '
            "application/octet-stream (curl: -H 'Content-Type: image/jpeg' "
            '--data-binary @photo.jpg; without -H curl sends '
            'application/x-www-form-urlencoded)')
    if not body:
        raise BadImage(400, 'empty request body: send an encoded image')
    if len(body) > max_bytes:
        raise BadImage(
            413, f'body of {len(body)} bytes is over the limit of '
            f'{max_bytes} bytes')
    try:
        with Image.open(io.BytesIO(body)) as header:
            width, height = header.size
    except Image.DecompressionBombError as err:
        raise BadImage(413, f'image too large: {err}') from None
    except Exception as err:  # PIL raises several types for non-images
        raise BadImage(
            400, f'body is not a readable image ({type(err).__name__}: '
            f'{err})') from None
    if width * height > max_pixels:
        raise BadImage(
            413, f'image of {width}x{height} pixels is over the limit of '
            f'{max_pixels} pixels; resize it before sending')
    img = mmcv.imfrombytes(body, flag='color', channel_order='bgr')
    if img is None or img.size == 0:
        raise BadImage(400, 'body is not a decodable image')
    return img
