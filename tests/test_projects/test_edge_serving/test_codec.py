"""Input checks of the server (cbnet_serving.codec)."""
import cv2
import numpy as np
import pytest
from serving_helpers import png_header

from cbnet_serving.codec import BadImage, decode_image


def test_decodes_png_and_jpeg_to_bgr():
    img = np.zeros((6, 10, 3), np.uint8)
    img[..., 2] = 200  # red in BGR
    ok, png = cv2.imencode('.png', img)
    out = decode_image(png.tobytes(), 'image/png')
    np.testing.assert_array_equal(out, img)
    ok, jpg = cv2.imencode('.jpg', img)
    out = decode_image(jpg.tobytes(), 'application/octet-stream')
    assert out.shape == (6, 10, 3)
    assert abs(int(out[..., 2].mean()) - 200) <= 3


@pytest.mark.parametrize('body,ctype,status,words', [
    (b'', 'image/png', 400, 'empty'),
    (b'this is not an image', 'image/png', 400, 'not a readable image'),
    (b'\x89PNG\r\n\x1a\n broken', 'image/png', 400, 'not a readable'),
    (b'abc', 'application/json', 415, 'Content-Type'),
    (b'abc', None, 415, 'Content-Type'),
    # what curl --data-binary sends without -H: the fix is named
    (b'\x89PNG', 'application/x-www-form-urlencoded', 415,
     "curl: -H 'Content-Type: image/jpeg' --data-binary @photo.jpg"),
    (png_header(20000, 20000), 'image/png', 413, 'too large'),
    (png_header(5000, 5000), 'image/png', 413, 'over the limit'),
])
def test_bad_input_is_a_4xx(body, ctype, status, words):
    with pytest.raises(BadImage, match=words) as err:
        decode_image(body, ctype)
    assert err.value.status == status


def test_body_size_limit():
    with pytest.raises(BadImage) as err:
        decode_image(b'x' * 11, 'image/png', max_bytes=10)
    assert err.value.status == 413
