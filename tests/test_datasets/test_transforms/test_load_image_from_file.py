import re

import numpy as np
import pytest
from mmcv.transforms import LoadImageFromFile
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


@pytest.mark.parametrize('dataset_type', ['CBNetCityscapesDataset',
                                          'CBNetFoggyCityscapesDataset'])
def test_dataset_runs_the_loader_its_config_names(cityscapes_like_root,
                                                  tmp_path, dataset_type):
    """The dataset leaves its pipeline alone: MMCV's loader stays MMCV's
    (a corrupt image: MMCV's own error), the checking loader named in the
    config raises ValueError naming the image."""
    import shutil

    from mmdet.registry import DATASETS
    root = str(tmp_path / 'cs')
    shutil.copytree(cityscapes_like_root, root)
    kwargs = dict(
        type=dataset_type,
        data_root=root,
        ann_file='annotations/instancesonly_filtered_gtFine_val.json',
        data_prefix=dict(img='leftImg8bit/val/'),
        test_mode=True)
    if dataset_type == 'CBNetFoggyCityscapesDataset':
        kwargs['beta'] = 0.02
    plain = DATASETS.build(dict(
        kwargs, pipeline=[dict(type='LoadImageFromFile', to_float32=True)]))
    assert type(plain.pipeline.transforms[0]) is LoadImageFromFile
    checked = DATASETS.build(dict(
        kwargs,
        pipeline=[dict(type='CBNetLoadImageFromFile', to_float32=True)]))
    loader = checked.pipeline.transforms[0]
    assert type(loader) is CBNetLoadImageFromFile and loader.to_float32
    path = checked.get_data_info(0)['img_path']
    assert checked[0]['img'].dtype == np.float32
    with open(path, 'wb') as f:
        f.write(b'not a png')
    with pytest.raises(ValueError, match=re.escape(path)):
        checked[0]
    with pytest.raises(AssertionError, match='failed to load image'):
        plain[0]  # MMCV's bare assert (gone under python -O)
