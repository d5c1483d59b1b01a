import json
import os.path as osp

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
