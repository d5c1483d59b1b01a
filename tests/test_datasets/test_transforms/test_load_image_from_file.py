import re

import numpy as np
import pytest
from mmcv.transforms import LoadImageFromFile
from PIL import Image

from cbnet_mmdet.datasets.transforms import (CBNetLoadImageFromFile,
                                             with_checked_loader)


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


def test_with_checked_loader_swaps_only_mmcvs_loader():
    built = CBNetLoadImageFromFile()
    pipeline = [
        dict(type='LoadImageFromFile', to_float32=True),
        dict(type='mmcv.LoadImageFromFile'),
        dict(type=LoadImageFromFile, backend_args=None),
        dict(type='LoadImageFromNDArray'),
        dict(type='LoadAnnotations', with_bbox=True),
        built,
    ]
    out = with_checked_loader(pipeline)
    assert [t['type'] for t in out[:3]] == [CBNetLoadImageFromFile] * 3
    # the arguments are kept, the input is not modified
    assert out[0]['to_float32'] is True and 'backend_args' in out[2]
    assert pipeline[0]['type'] == 'LoadImageFromFile'
    assert out[3:5] == pipeline[3:5] and out[5] is built
    assert with_checked_loader([]) == []


def test_dataset_runs_the_checking_loader(cityscapes_like_root, tmp_path):
    """A config naming MMCV's loader gets ours inside CBNet datasets: a
    corrupt image raises ValueError naming it (MMCV: a bare assert)."""
    import shutil

    from cbnet_mmdet.datasets import CBNetCityscapesDataset
    root = str(tmp_path / 'cs')
    shutil.copytree(cityscapes_like_root, root)
    dataset = CBNetCityscapesDataset(
        data_root=root,
        ann_file='annotations/instancesonly_filtered_gtFine_val.json',
        data_prefix=dict(img='leftImg8bit/val/'),
        test_mode=True,
        pipeline=[dict(type='LoadImageFromFile', to_float32=True)])
    loader = dataset.pipeline.transforms[0]
    assert type(loader) is CBNetLoadImageFromFile and loader.to_float32
    path = dataset.get_data_info(0)['img_path']
    assert dataset[0]['img'].dtype == np.float32
    with open(path, 'wb') as f:
        f.write(b'not a png')
    with pytest.raises(ValueError, match=re.escape(path)):
        dataset[0]
