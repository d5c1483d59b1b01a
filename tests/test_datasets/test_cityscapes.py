import json
import os
import os.path as osp
import re
import shutil

import cv2
import pytest
from mmengine.config import Config
from mmengine.registry import init_default_scope

from cbnet_mmdet.datasets import (CBNetCityscapesDataset,
                                  CBNetFoggyCityscapesDataset,
                                  CBNetPairedFoggyDataset)
from cbnet_mmdet.datasets.cityscapes_paths import (FOGGY_BETAS, foggy_path,
                                                   split_beta)

ANN = 'annotations/instancesonly_filtered_gtFine_val.json'
init_default_scope('mmdet')
PIPELINE = [
    dict(type='CBNetLoadImageFromFile'),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
    dict(type='PackDetInputs'),
]


def _dataset(root, cls=CBNetCityscapesDataset, pipeline=PIPELINE, **kw):
    kw.setdefault('ann_file', ANN)
    return cls(data_root=root, data_prefix=dict(img='leftImg8bit/val/'),
               test_mode=True, pipeline=pipeline, **kw)


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


def test_split_beta_inverts_foggy_path():
    clear = 'leftImg8bit/val/lindau/lindau_000001_000019_leftImg8bit.png'
    for beta in FOGGY_BETAS:
        foggy = foggy_path(clear, beta)
        twin, got = split_beta(osp.basename(foggy))
        assert (twin, got) == (osp.basename(clear), str(beta))
    assert split_beta(clear) == (clear, 'clear')
    assert split_beta('x_foggy_beta_0.02.jpg') == ('x_foggy_beta_0.02.jpg',
                                                   'clear')


@pytest.fixture
def broken_root(cityscapes_like_root, tmp_path):
    root = tmp_path / 'cs'
    shutil.copytree(cityscapes_like_root, root,
                    ignore=shutil.ignore_patterns('gtFine', 'depth'))
    return str(root)


def test_missing_annotation_file_names_the_fix_that_applies(broken_root):
    os.remove(osp.join(broken_root, ANN))
    # no gtFine (what the demo's stand-in leaves when its JSON is gone
    # too): where the data comes from, the stand-in's command first-hand
    with pytest.raises(FileNotFoundError) as err:
        _dataset(broken_root)
    message = str(err.value)
    assert ANN in message
    assert (f'{broken_root} has no gtFine: get Cityscapes into it') in message
    assert (f'python tools/misc/generate_cityscapes_like.py {broken_root} '
            f'--convert') in message
    # a gtFine folder: convert it
    os.makedirs(osp.join(broken_root, 'gtFine'))
    with pytest.raises(FileNotFoundError,
                       match=re.escape('convert its gtFine: python tools/'
                                       'dataset_converters/cityscapes.py '
                                       f'{broken_root}')):
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


# --------------------------------------------------------------------------
# Malformed input: one check, one exact message (file, annotation id, what)
# --------------------------------------------------------------------------
#: Every dataset of the package that reads the converter's COCO JSON: the
#: same checks and messages in each (the paired CBNet-DD one included).
DATASET_CLASSES = {
    'clear': (CBNetCityscapesDataset, {}),
    'foggy': (CBNetFoggyCityscapesDataset, dict(beta=0.02)),
    'paired': (CBNetPairedFoggyDataset, dict(beta=0.02)),
}
#: Id given to the mutated annotation, so that the message must name it.
BAD_ID = 4242


def mutate_annotation(root: str, field: str, value) -> tuple:
    """Set ``field`` of the first annotation of the first image that has
    one, and give that annotation the id :data:`BAD_ID`.

    Returns:
        tuple[str, dict]: The annotation file and the image entry.
    """
    path = osp.join(root, ANN)
    with open(path) as f:
        coco = json.load(f)
    ann = coco['annotations'][0]
    image = next(im for im in coco['images'] if im['id'] == ann['image_id'])
    assert all(a['id'] != BAD_ID for a in coco['annotations'])
    ann.update({'id': BAD_ID, field: value})
    with open(path, 'w') as f:
        json.dump(coco, f)
    return path, image


@pytest.mark.parametrize('kind', sorted(DATASET_CLASSES))
@pytest.mark.parametrize('field,value,problem', [
    ('bbox', [1.0, 2.0, 3.0],
     'bbox must be 4 finite numbers [x, y, w, h], got [1.0, 2.0, 3.0]'),
    ('bbox', [1.0, float('nan'), 3.0, 4.0],
     'bbox must be 4 finite numbers [x, y, w, h], got [1.0, nan, 3.0, 4.0]'),
    ('bbox', 'abc', "bbox must be 4 finite numbers [x, y, w, h], got 'abc'"),
    ('segmentation', [[1.0, 1.0, 5.0, 5.0]],
     'polygons need an even number (>= 6) of coordinates, got '
     '[1.0, 1.0, 5.0, 5.0]'),
    ('segmentation', [[1.0, 1.0, 9.0, 1.0, 9.0]],
     'polygons need an even number (>= 6) of coordinates, got '
     '[1.0, 1.0, 9.0, 1.0, 9.0]'),
    ('segmentation', dict(size=[7, 9], counts='0`0'),
     'RLE size [7, 9] is not the image size [128, 256]'),
    ('segmentation', dict(size=[128, 256], counts='!!!!'),
     "undecodable RLE counts '!!!!'"),
    ('segmentation', [], 'empty segmentation'),
    ('segmentation', 7, 'segmentation must be polygons or RLE, got int'),
])
def test_malformed_annotation_message(broken_root, kind, field, value,
                                      problem):
    cls, kwargs = DATASET_CLASSES[kind]
    ann_file, image = mutate_annotation(broken_root, field, value)
    with pytest.raises(ValueError) as excinfo:
        _dataset(broken_root, cls, **kwargs)
    assert str(excinfo.value) == (
        f'annotation file {ann_file}: annotation {BAD_ID} of image '
        f"{image['file_name']!r} (id {image['id']}): {problem}")


@pytest.mark.parametrize('kind', sorted(DATASET_CLASSES))
def test_no_training_image_left_message(broken_root, kind):
    cls, kwargs = DATASET_CLASSES[kind]
    path = osp.join(broken_root, ANN)
    with open(path) as f:
        coco = json.load(f)
    for ann in coco['annotations']:
        ann['iscrowd'] = 1
    with open(path, 'w') as f:
        json.dump(coco, f)
    filter_cfg = dict(filter_empty_gt=True, min_size=32)
    with pytest.raises(ValueError) as excinfo:
        cls(data_root=broken_root, ann_file=ANN,
            data_prefix=dict(img='leftImg8bit/val/'), test_mode=False,
            filter_cfg=filter_cfg, pipeline=PIPELINE, **kwargs)
    assert str(excinfo.value) == (
        f'no training image left from {path} ({len(coco["images"])} listed)'
        f' after filter_cfg={filter_cfg} (images without non-crowd '
        f'instances are dropped)')


def demo_train_pipeline() -> list:
    """The demo config's training pipeline (its own loading transform)."""
    cfg = Config.fromfile(osp.join(
        osp.dirname(__file__), '..', '..', 'configs', 'demo',
        'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'))
    return cfg.train_pipeline


def test_image_size_differs_from_annotation_message(broken_root):
    ds = _dataset(broken_root, pipeline=demo_train_pipeline())
    info = ds.get_data_info(0)
    path = info['img_path']
    cv2.imwrite(path, cv2.imread(path)[:40, :60])
    with pytest.raises(ValueError) as excinfo:
        ds[0]
    assert str(excinfo.value) == (
        f"image {path} is 40x60 (HxW) but its annotations say "
        f"{info['height']}x{info['width']}")
