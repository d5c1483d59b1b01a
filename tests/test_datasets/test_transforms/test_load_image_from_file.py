import re

import numpy as np
import pytest
from PIL import Image

from cbnet_mmdet.datasets.transforms import CBNetLoadImageFromFile


@pytest.fixture
def png(tmp_path):
    path = str(tmp_path / 'x_leftImg8bit.png')
    rgb = np.random.default_rng(0).integers(0, 255, (48, 64, 3), np.uint8)
    Image.fromarray(rgb).save(path)
    return path, rgb


def test_loads_like_mmcv(png):
    path, rgb = png
    out = CBNetLoadImageFromFile()(dict(img_path=path))
    np.testing.assert_array_equal(out['img'], rgb[..., ::-1])  # BGR
    assert out['ori_shape'] == (48, 64)


def test_missing(tmp_path):
    path = str(tmp_path / 'nope.png')
    with pytest.raises(FileNotFoundError, match=re.escape(path)):
        CBNetLoadImageFromFile()(dict(img_path=path))


@pytest.mark.parametrize('kind', ['garbage', 'bad_pixels', 'truncated'])
def test_corrupt(png, kind):
    # (a bogus chunk length is left out: OpenCV spends seconds on it)
    path, _ = png
    with open(path, 'rb') as f:
        data = f.read()
    n = len(data)
    with open(path, 'wb') as f:
        f.write({
            'garbage': b'garbage' * 4,
            'bad_pixels': data[:100] + bytes(n - 200) + data[-100:],
            'truncated': data[:n // 2],
        }[kind])
    with pytest.raises(ValueError, match=re.escape(path)):
        CBNetLoadImageFromFile()(dict(img_path=path))
    assert CBNetLoadImageFromFile(ignore_empty=True)(
        dict(img_path=path)) is None
