import json
import os
import os.path as osp
import re
import shutil

import pytest
from mmengine.registry import init_default_scope

from cbnet_mmdet.datasets import (CBNetCityscapesDataset,
                                  CBNetFoggyCityscapesDataset)

ANN = 'annotations/instancesonly_filtered_gtFine_val.json'
init_default_scope('mmdet')
PIPELINE = [
    dict(type='CBNetLoadImageFromFile'),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
    dict(type='PackDetInputs'),
]


def _dataset(root, cls=CBNetCityscapesDataset, **kw):
    kw.setdefault('ann_file', ANN)
    return cls(data_root=root, data_prefix=dict(img='leftImg8bit/val/'),
               test_mode=True, pipeline=PIPELINE, **kw)


def test_reads_converted_annotations(cityscapes_like_root):
    ds = _dataset(cityscapes_like_root)
    assert len(ds) == 3  # the empty image is kept in test mode
    assert ds.metainfo['classes'] == ('person', 'rider', 'car', 'truck',
                                      'bus', 'train', 'motorcycle',
                                      'bicycle')
    with open(osp.join(cityscapes_like_root, ANN)) as f:
        coco = json.load(f)
    for i in range(len(ds)):
        info = ds.get_data_info(i)
        n = sum(a['image_id'] == info['img_id'] for a in coco['annotations'])
        assert len(info['instances']) == n
        out = ds[i]
        assert tuple(out['inputs'].shape) == (3, 128, 256)
        assert len(out['data_samples'].gt_instances) == n - sum(
            inst['ignore_flag'] for inst in info['instances'])


def test_foggy_paths(cityscapes_like_root):
    clear = _dataset(cityscapes_like_root)
    for beta in (0.005, 0.01, 0.02):
        ds = _dataset(cityscapes_like_root, CBNetFoggyCityscapesDataset,
                      beta=beta)
        for i in range(len(ds)):
            info = ds.get_data_info(i)
            assert info['clear_img_path'] == clear.get_data_info(
                i)['img_path']
            assert info['img_path'].endswith(
                f'_leftImg8bit_foggy_beta_{beta}.png')
            assert '/leftImg8bit_foggy/val/' in info['img_path']
            assert osp.isfile(info['img_path'])
            assert info['instances'] == clear.get_data_info(i)['instances']
        assert ds[0]['data_samples'].img_path == ds.get_data_info(
            0)['img_path']
    with pytest.raises(ValueError, match='0.03'):
        _dataset(cityscapes_like_root, CBNetFoggyCityscapesDataset,
                 beta=0.03)


@pytest.fixture
def broken_root(cityscapes_like_root, tmp_path):
    root = tmp_path / 'cs'
    shutil.copytree(cityscapes_like_root, root,
                    ignore=shutil.ignore_patterns('gtFine', 'depth'))
    return str(root)


def test_missing_annotation_file(broken_root):
    os.remove(osp.join(broken_root, ANN))
    with pytest.raises(FileNotFoundError, match=re.escape(ANN)):
        _dataset(broken_root)


def test_invalid_json(broken_root):
    with open(osp.join(broken_root, ANN), 'w') as f:
        f.write('{"images": [')
    with pytest.raises(ValueError, match=re.escape(ANN) + '.*not valid'):
        _dataset(broken_root)


def test_missing_image_folder(broken_root):
    shutil.rmtree(osp.join(broken_root, 'leftImg8bit', 'val'))
    with pytest.raises(FileNotFoundError, match='leftImg8bit/val'):
        _dataset(broken_root)


def test_image_listed_but_missing(broken_root):
    ds = _dataset(broken_root)
    path = ds.get_data_info(1)['img_path']
    os.remove(path)
    with pytest.raises(FileNotFoundError, match=re.escape(path)):
        _dataset(broken_root)
    _dataset(broken_root, check_files=False)  # opt out


def test_missing_foggy_image(broken_root):
    ds = _dataset(broken_root, CBNetFoggyCityscapesDataset, beta=0.01)
    path = ds.get_data_info(2)['img_path']
    os.remove(path)
    with pytest.raises(FileNotFoundError, match=re.escape(path)):
        _dataset(broken_root, CBNetFoggyCityscapesDataset, beta=0.01)
    _dataset(broken_root, CBNetFoggyCityscapesDataset, beta=0.02)


def test_corrupt_image_in_pipeline(broken_root):
    ds = _dataset(broken_root)
    path = ds.get_data_info(0)['img_path']
    with open(path, 'rb') as f:
        data = f.read()
    with open(path, 'wb') as f:  # truncated
        f.write(data[:len(data) // 2])
    with pytest.raises(ValueError, match=re.escape(path)):
        ds[0]
