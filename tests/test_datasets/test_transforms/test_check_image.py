"""Bad input through MMDetection's inference API, with our configs (issue
26): an empty image file, a 2-D array, a PNG passed as the checkpoint.

Each fails with an error naming the input and the fix, not deep inside
OpenCV or MMEngine, and never with torch's advice to load with
``weights_only=False``. That every shipped test pipeline has the checks is
tested with the other per-config checks of MMDet's inference API
(tests/test_e2e/test_mmdet_inference.py).
"""
import os.path as osp

import numpy as np
import pytest
import torch
from mmdet.apis import DetInferencer, inference_detector, init_detector
from mmdet.registry import MODELS, TRANSFORMS
from mmengine.config import Config
from mmengine.registry import init_default_scope

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.datasets.transforms import CBNetCheckImage

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.dirname(
    osp.abspath(__file__)))))
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')


@pytest.fixture(scope='module')
def demo(tmp_path_factory):
    tmp = tmp_path_factory.mktemp('bad_input')
    cfg = Config.fromfile(DEMO)
    init_default_scope('mmdet')
    torch.manual_seed(0)
    model = MODELS.build(cfg.model)
    model.init_weights()
    ckpt = str(tmp / 'demo.pth')
    torch.save(dict(state_dict=model.state_dict(), meta=dict()), ckpt)
    inferencer = DetInferencer(model=DEMO, weights=ckpt, device='cpu',
                               show_progress=False)
    return dict(tmp=tmp, ckpt=ckpt, inferencer=inferencer)


def test_empty_image_file_named(demo):
    empty = demo['tmp'] / 'empty.png'
    empty.write_bytes(b'')
    with pytest.raises(ValueError, match=f'{empty} is empty'):
        demo['inferencer'](str(empty))


def test_missing_image_file_named(demo):
    missing = str(demo['tmp'] / 'nope.png')
    with pytest.raises(FileNotFoundError, match=f'image not found: '
                       f'{missing}'):
        demo['inferencer'](missing)


@pytest.mark.parametrize('shape', [(64, 128), (64, 128, 4)])
def test_array_without_three_channels_refused(demo, shape):
    array = np.zeros(shape, np.uint8)
    with pytest.raises(ValueError, match=r'the input array: the image has '
                       rf'shape \({shape[0]}, {shape[1]}.*H x W x 3'):
        demo['inferencer'](array)
    model = init_detector(DEMO, demo['ckpt'], device='cpu')
    with pytest.raises(ValueError, match='cv2.COLOR_GRAY2BGR'):
        inference_detector(model, array)


def test_good_array_and_file_predict_as_without_the_check(demo):
    """A good H x W x 3 array, and the same image as a PNG file, give the
    model's predictions on a pipeline without CBNetCheckImage (the check
    changes nothing)."""
    import cv2
    from mmcv.transforms import Compose
    rng = np.random.default_rng(0)
    image = rng.integers(0, 255, (64, 128, 3), dtype=np.uint8)
    png = str(demo['tmp'] / 'good.png')
    cv2.imwrite(png, image)
    inferencer = demo['inferencer']
    cfg = Config.fromfile(DEMO)
    steps = [t for t in cfg.test_dataloader.dataset.pipeline
             if t['type'] not in ('CBNetCheckImage', 'LoadAnnotations')]
    steps[0] = dict(type='mmdet.LoadImageFromNDArray')
    item = Compose(steps)(dict(img=image.copy()))
    with torch.no_grad():
        expected = inferencer.model.test_step(dict(
            inputs=[item['inputs']],
            data_samples=[item['data_samples']]))[0].pred_instances
    assert len(expected) > 0  # random weights still detect something
    for source in (image, png):
        got = inferencer(source, return_datasamples=True)[
            'predictions'][0].pred_instances
        torch.testing.assert_close(got.bboxes, expected.bboxes)
        torch.testing.assert_close(got.scores, expected.scores)
        assert torch.equal(got.labels, expected.labels)


@pytest.mark.parametrize('via', ['init_checked_detector', 'read_checkpoint'])
def test_png_as_checkpoint_refused_without_weights_only_advice(demo, via):
    """Where the project loads (its inference tools; read_checkpoint:
    CBNetRunner's check); MMDetection's own init_detector / DetInferencer
    raise torch's error (the import replaces no MMEngine loader, issue
    43)."""
    from cbnet_mmdet.utils.checkpoint.files import read_checkpoint
    from cbnet_mmdet.utils.checkpoint.fit import init_checked_detector
    png = str(demo['tmp'] / 'picture.png')
    import cv2
    cv2.imwrite(png, np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(ValueError) as err:
        if via == 'init_checked_detector':
            init_checked_detector(DEMO, png, device='cpu')
        else:
            read_checkpoint(png)
    message = str(err.value)
    assert f'{png} is not a PyTorch checkpoint (it looks like a PNG ' \
        f'image)' in message
    assert 'weights_only' not in message
    assert err.value.__cause__ is None


def test_check_image_keeps_a_good_image():
    check = TRANSFORMS.build(dict(type='CBNetCheckImage'))
    assert isinstance(check, CBNetCheckImage)
    img = np.ones((5, 6, 3), np.uint8)
    results = dict(img=img, img_path='a.png')
    assert check(results) is results and results['img'] is img
    with pytest.raises(ValueError, match='a.png: the image is empty'):
        check(dict(img=np.ones((0, 6, 3), np.uint8), img_path='a.png'))
    with pytest.raises(ValueError, match='no image was loaded from a.png'):
        check(dict(img=None, img_path='a.png'))
