"""Tiny detectors and a tiny paired (clear + foggy) dataset for the tests."""
import json
import os.path as osp

import mmdet
import numpy as np
import pytest
from mmcv import imwrite
from mmdet.utils import register_all_modules
from mmengine.config import Config, ConfigDict

from cbnet_mmdet.datasets.cityscapes_paths import foggy_path

# MMEngine's BaseModel builds `data_preprocessor` from the default scope.
register_all_modules()

MMDET_MODELS = osp.join(
    osp.dirname(mmdet.__file__), '.mim', 'configs', '_base_', 'models')
#: (B, G, R) means / stds of ImageNet, as in MMDetection's configs.
MEAN, STD = [123.675, 116.28, 103.53], [58.395, 57.12, 57.375]
CLASSES = ('person', 'rider', 'car', 'truck', 'bus', 'train', 'motorcycle',
           'bicycle')
#: Feature channels of the tiny detectors.
C = 16


def _shrink_roi_head(roi_head: dict) -> None:
    heads = roi_head['bbox_head']
    for head in heads if isinstance(heads, list) else [heads]:
        head.update(in_channels=C, fc_out_channels=32, num_classes=8)
    roi_head['bbox_roi_extractor']['out_channels'] = C
    roi_head['mask_roi_extractor']['out_channels'] = C
    roi_head['mask_head'].update(
        in_channels=C, conv_out_channels=C, num_classes=8, num_convs=1)


def tiny_detector_cfg(base: str = 'mask-rcnn_r50_fpn.py',
                      roi_head_type: str = None) -> dict:
    """An MMDetection Mask R-CNN (or cascade) with ResNet-18, 16 channels.

    Args:
        base (str): File under mmdet's ``configs/_base_/models``.
        roi_head_type (str, optional): Replaces the RoI head's type.

    Returns:
        dict: The ``model`` config, without ``data_preprocessor``.
    """
    model = Config.fromfile(osp.join(MMDET_MODELS, base)).model.to_dict()
    if roi_head_type is not None:
        model['roi_head']['type'] = roi_head_type
    model.pop('data_preprocessor')
    model['backbone'].update(
        depth=18, init_cfg=None, base_channels=16, num_stages=4)
    model['neck'].update(in_channels=[16, 32, 64, 128], out_channels=C)
    model['rpn_head'].update(in_channels=C, feat_channels=C)
    _shrink_roi_head(model['roi_head'])
    rpn = model['train_cfg']['rpn']
    rpn['sampler']['num'] = 64
    model['train_cfg']['rpn_proposal'].update(nms_pre=200, max_per_img=64)
    rcnns = model['train_cfg']['rcnn']
    for rcnn in rcnns if isinstance(rcnns, list) else [rcnns]:
        rcnn['sampler']['num'] = 32
    model['test_cfg']['rpn'].update(nms_pre=200, max_per_img=64)
    model['test_cfg']['rcnn'].update(max_per_img=10)
    return model


def paired_preprocessor_cfg() -> dict:
    return dict(
        type='CBNetPairedDataPreprocessor',
        mean=MEAN,
        std=STD,
        bgr_to_rgb=True,
        pad_size_divisor=32)


def distiller_cfg(base: str = 'mask-rcnn_r50_fpn.py',
                  roi_head_type: str = None,
                  **kwargs) -> dict:
    # ConfigDict, as from a config file: MMDet reads `train_cfg.rpn`
    return ConfigDict(
        type='CBNetDistiller',
        detector=tiny_detector_cfg(base, roi_head_type),
        data_preprocessor=paired_preprocessor_cfg(),
        **kwargs)


def write_paired_cityscapes(root: str,
                            num_images: int = 4,
                            beta: float = 0.02,
                            size=(64, 96)) -> str:
    """Write clear/foggy PNGs and a COCO JSON in Cityscapes' layout.

    Each image holds 2 axis-aligned boxes of random classes on a textured
    background; the foggy twin is the clear image blended with grey
    (``0.6 * clear + 0.4 * 200``).

    Args:
        root (str): Output folder.
        num_images (int): Number of scenes.
        beta (float): Fog density in the foggy file names.
        size (tuple[int, int]): (H, W) in pixels.

    Returns:
        str: Path of the COCO JSON (relative image names under
        ``leftImg8bit/train/``).
    """
    rng = np.random.default_rng(0)
    h, w = size
    images, annotations = [], []
    for i in range(num_images):
        name = f'aachen/aachen_{i:06d}_000019_leftImg8bit.png'
        clear = rng.integers(0, 80, (h, w, 3)).astype(np.uint8)
        for j in range(2):
            x0, y0 = int(rng.integers(0, w - 24)), int(rng.integers(0, h - 24))
            bw, bh = int(rng.integers(12, 24)), int(rng.integers(12, 24))
            clear[y0:y0 + bh, x0:x0 + bw] = rng.integers(120, 255, 3)
            annotations.append(
                dict(
                    id=len(annotations) + 1,
                    image_id=i,
                    category_id=int(rng.integers(1, 9)),
                    bbox=[x0, y0, bw, bh],
                    area=bw * bh,
                    iscrowd=0,
                    segmentation=[[
                        x0, y0, x0 + bw, y0, x0 + bw, y0 + bh, x0, y0 + bh
                    ]]))
        foggy = (0.6 * clear + 0.4 * 200).round().astype(np.uint8)
        clear_path = osp.join(root, 'leftImg8bit', 'train', name)
        imwrite(clear, clear_path)
        imwrite(foggy, foggy_path(clear_path, beta))
        images.append(dict(id=i, file_name=name, height=h, width=w))
    categories = [dict(id=k + 1, name=n) for k, n in enumerate(CLASSES)]
    ann_file = osp.join(root, 'instancesonly_filtered_gtFine_train.json')
    with open(ann_file, 'w') as f:
        json.dump(
            dict(
                images=images,
                annotations=annotations,
                categories=categories), f)
    return ann_file


@pytest.fixture(scope='module')
def paired_root(tmp_path_factory) -> str:
    root = str(tmp_path_factory.mktemp('paired_cityscapes'))
    write_paired_cityscapes(root)
    return root


@pytest.fixture
def make_distiller_cfg():
    """``make_distiller_cfg(base='mask-rcnn_r50_fpn.py', **kwargs)``."""
    return distiller_cfg


@pytest.fixture
def make_detector_cfg():
    """``make_detector_cfg(base='mask-rcnn_r50_fpn.py', roi_head_type=None)``:
    the tiny MMDetection detector config (see :func:`tiny_detector_cfg`)."""
    return tiny_detector_cfg
