import json
import os
import os.path as osp
import re
import shutil

import cv2
import pytest
from mmdet.registry import DATASETS

import cbnet_mmdet  # noqa: F401

CLASSES = ('person', 'rider', 'car', 'truck', 'bus', 'train', 'motorcycle',
           'bicycle')


@pytest.fixture
def ann_file(tmp_path):
    """COCO JSON of two annotated images (no pixels needed to parse)."""
    images = [
        dict(id=i, file_name=f'aachen/aachen_{i:06d}_000019_leftImg8bit.png',
             height=32, width=64) for i in range(2)
    ]
    annotations = [
        dict(id=i + 1, image_id=i, category_id=3, bbox=[2, 2, 10, 10],
             area=100, iscrowd=0,
             segmentation=[[2, 2, 12, 2, 12, 12, 2, 12]]) for i in range(2)
    ]
    categories = [dict(id=k + 1, name=n) for k, n in enumerate(CLASSES)]
    path = tmp_path / 'train.json'
    path.write_text(
        json.dumps(dict(images=images, annotations=annotations,
                        categories=categories)))
    return str(path)


def build(ann_file, pipeline=(), **kwargs):
    kwargs.setdefault('check_files', False)  # no pixels in `ann_file`
    return DATASETS.build(
        dict(
            type='CBNetPairedFoggyDataset',
            ann_file=ann_file,
            data_root=osp.dirname(ann_file),
            data_prefix=dict(img='leftImg8bit/train/'),
            pipeline=list(pipeline),
            **kwargs))


def test_foggy_paths(ann_file):
    dataset = build(ann_file, beta=0.01)
    assert len(dataset) == 2
    info = dataset.get_data_info(1)
    root = osp.dirname(ann_file)
    assert info['img_path'] == osp.join(
        root, 'leftImg8bit/train/aachen/aachen_000001_000019_leftImg8bit.png')
    assert info['foggy_img_path'] == osp.join(
        root, 'leftImg8bit_foggy/train/aachen/'
        'aachen_000001_000019_leftImg8bit_foggy_beta_0.01.png')
    assert info['instances'][0]['bbox_label'] == 2  # car
    assert dataset.metainfo['classes'] == CLASSES


def test_rejects_photometric_and_bad_beta(ann_file):
    with pytest.raises(ValueError, match='PhotoMetricDistortion'):
        build(ann_file, pipeline=[
            dict(type='CBNetLoadPairedImageFromFile'),
            dict(type='PhotoMetricDistortion')
        ])
    nested = dict(
        type='RandomApply',
        transforms=[dict(type='RandomFlip', prob=1.),
                    dict(type='YOLOXHSVRandomAug')])
    with pytest.raises(ValueError, match='YOLOXHSVRandomAug'):
        build(ann_file, pipeline=[nested])
    with pytest.raises(ValueError, match='Pad .*pad_size_divisor'):
        build(ann_file, pipeline=[dict(type='Pad', size_divisor=32)])
    with pytest.raises(ValueError, match='beta'):
        build(ann_file, beta=0.03)
    # geometric transforms are fine
    build(ann_file, pipeline=[
        dict(type='CBNetLoadPairedImageFromFile'),
        dict(type='RandomFlip', prob=0.5),
        dict(type='RandomCrop', crop_size=(16, 16))
    ])


@pytest.fixture
def paired_copy(cityscapes_like_root, tmp_path):
    root = str(tmp_path / 'cs')
    shutil.copytree(cityscapes_like_root, root,
                    ignore=shutil.ignore_patterns('gtFine', 'depth'))
    return root


def build_val(root, **kwargs):
    return DATASETS.build(
        dict(type='CBNetPairedFoggyDataset',
             ann_file='annotations/instancesonly_filtered_gtFine_val.json',
             data_root=root, data_prefix=dict(img='leftImg8bit/val/'),
             test_mode=True, **kwargs))


@pytest.mark.parametrize('which', ['img_path', 'foggy_img_path'])
def test_missing_clear_or_foggy_image_names_it(paired_copy, which):
    path = build_val(paired_copy).get_data_info(1)[which]
    os.remove(path)
    with pytest.raises(FileNotFoundError,
                       match=r'^1 image\(s\) listed in .* are missing, '
                       r'e\.g\.:\n  ' + re.escape(path) + '$'):
        build_val(paired_copy)
    build_val(paired_copy, check_files=False)  # opt out


def test_image_size_differs_from_annotation(paired_copy):
    ds = build_val(paired_copy, pipeline=[
        dict(type='CBNetLoadPairedImageFromFile')])
    info = ds.get_data_info(0)
    for key in ('img_path', 'foggy_img_path'):  # both halves agree
        cv2.imwrite(info[key], cv2.imread(info[key])[:40, :60])
    with pytest.raises(ValueError) as excinfo:
        ds[0]
    assert str(excinfo.value) == (
        f"CBNetLoadPairedImageFromFile: image {info['img_path']} is 40x60 "
        f"(HxW) but its annotations say {info['height']}x{info['width']}")
