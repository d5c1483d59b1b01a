"""CBNetAddFoggyTwin: CBNet-DD's clear/foggy pair made on the
fly from a clear photograph, carried through the same crop, flip and
resize, into CBNetPairedDataPreprocessor."""
import numpy as np
import pytest
import torch
from mmcv import imwrite
from mmcv.transforms import Compose
from mmdet.registry import MODELS, TRANSFORMS
from mmengine.registry import init_default_scope

import cbnet_mmdet  # noqa: F401

init_default_scope('mmdet')  # MMDet's transforms in mmcv's Compose

H, W = 120, 200


@pytest.fixture
def clear_file(tmp_path):
    """A clear image whose pixels encode their coordinates (x, y, 77):
    the clear half of any crop/flip/resize tells where each pixel came
    from."""
    y, x = np.mgrid[:H, :W]
    clear = np.stack([x, y, np.full_like(x, 77)], -1).astype(np.uint8)
    path = str(tmp_path / 'clear.png')
    imwrite(clear, path)
    return path, clear


def test_twin_is_the_fog_of_the_clear_image():
    img = np.random.RandomState(0).randint(0, 256, (30, 40, 3), np.uint8)
    kwargs = dict(beta=0.03, atmospheric_light=(0.7, 0.8, 0.9))
    out = TRANSFORMS.build(dict(type='CBNetAddFoggyTwin', **kwargs))(
        dict(img=img.copy()))
    assert out['img'].shape == (30, 40, 6) and out['img'].dtype == np.uint8
    np.testing.assert_array_equal(out['img'][..., 3:], img)
    alone = TRANSFORMS.build(dict(type='CBNetAddFog', **kwargs))(
        dict(img=img.copy()))
    np.testing.assert_array_equal(out['img'][..., :3], alone['img'])
    assert out['fog_beta'] == 0.03
    assert not np.array_equal(out['img'][..., :3], img)


def test_skipped_twin_is_the_clear_image():
    img = np.random.RandomState(1).randint(0, 256, (10, 12, 3), np.uint8)
    out = TRANSFORMS.build(dict(type='CBNetAddFoggyTwin', prob=0.0))(
        dict(img=img.copy()))
    np.testing.assert_array_equal(out['img'], np.concatenate([img, img],
                                                             axis=2))
    assert out['fog_beta'] == 0.0


@pytest.mark.parametrize('seed', range(5))
def test_same_crop_flip_resize(clear_file, seed):
    path, clear = clear_file
    beta = 0.04
    # the foggy twin of the whole photograph, computed on its own
    full_foggy = TRANSFORMS.build(dict(type='CBNetAddFog', beta=beta))(
        dict(img=clear.copy()))['img']
    pipeline = Compose([
        dict(type='LoadImageFromFile'),
        dict(type='CBNetAddFoggyTwin', beta=beta),
        dict(
            type='RandomResize',
            scale=(260, 150),
            ratio_range=(0.5, 1.0),
            keep_ratio=True,
            interpolation='nearest'),
        dict(type='RandomCrop', crop_size=(40, 60)),
        dict(
            type='RandomFlip', prob=0.5, direction=['horizontal', 'vertical']),
    ])
    np.random.seed(seed)
    img = pipeline(dict(img_path=path))['img']
    assert img.shape[2] == 6 and img.dtype == np.uint8
    foggy_half, clear_half = img[..., :3], img[..., 3:]
    assert (clear_half[..., 2] == 77).all()
    xs, ys = clear_half[..., 0].astype(int), clear_half[..., 1].astype(int)
    assert xs.max() - xs.min() < W - 1  # it did crop
    # every foggy pixel is the fog of the whole photograph at the place
    # its clear twin came from: same geometry, fog from the full-image rows
    np.testing.assert_array_equal(foggy_half, full_foggy[ys, xs])


def test_into_paired_data_preprocessor(clear_file):
    path, _ = clear_file
    pipeline = Compose([
        dict(type='LoadImageFromFile'),
        dict(type='LoadAnnotations', with_bbox=True),
        dict(type='CBNetAddFoggyTwin', beta=(0.005, 0.02)),
        dict(type='RandomCrop', crop_size=(96, 64)),
        dict(type='PackDetInputs'),
    ])
    np.random.seed(0)
    data = pipeline(
        dict(
            img_path=path,
            height=H,
            width=W,
            instances=[
                dict(
                    bbox=[10.0, 10.0, 90.0, 60.0], bbox_label=0, ignore_flag=0)
            ]))
    assert tuple(data['inputs'].shape) == (6, 64, 96)
    pre = MODELS.build(
        dict(
            type='CBNetPairedDataPreprocessor',
            mean=[0, 0, 0],
            std=[1, 1, 1],
            bgr_to_rgb=True,
            pad_size_divisor=32))
    out = pre(
        dict(inputs=[data['inputs']], data_samples=[data['data_samples']]),
        training=True)
    x = out['inputs']
    assert tuple(x.shape) == (1, 6, 64, 96)
    raw = data['inputs'].float()
    # channels 0-2: the foggy half, RGB; 3-5: the clear half, RGB
    assert torch.equal(x[0, :3], raw[:3].flip(0))
    assert torch.equal(x[0, 3:], raw[3:].flip(0))


def test_paired_image_refused():
    twin = TRANSFORMS.build(dict(type='CBNetAddFoggyTwin'))
    with pytest.raises(ValueError, match='CBNetAddFoggyTwin on the clear'):
        twin(dict(img=np.zeros((8, 8, 6), np.uint8)))
