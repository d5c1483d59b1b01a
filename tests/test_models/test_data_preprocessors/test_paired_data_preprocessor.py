import pytest
import torch
from mmdet.registry import MODELS
from mmdet.testing import demo_mm_inputs

import cbnet_mmdet  # noqa: F401


def make_preprocessor_cfg():
    """CBNet-DD's paired preprocessor with ImageNet's (B, G, R) statistics,
    as the CBNet-DD configs set it."""
    return dict(
        type='CBNetPairedDataPreprocessor',
        mean=[123.675, 116.28, 103.53],
        std=[58.395, 57.12, 57.375],
        bgr_to_rgb=True,
        pad_size_divisor=32)


def test_halves_processed_like_single_images():
    pre = MODELS.build(make_preprocessor_cfg())
    paired = demo_mm_inputs(2, [(6, 40, 50), (6, 64, 30)], num_items=[1, 1])
    foggy = dict(inputs=[x[:3].clone() for x in paired['inputs']],
                 data_samples=paired['data_samples'])
    clear = dict(inputs=[x[3:].clone() for x in paired['inputs']],
                 data_samples=paired['data_samples'])
    out = pre(paired, True)
    assert out['inputs'].shape == (2, 6, 64, 64)  # padded to 32
    torch.testing.assert_close(out['inputs'][:, :3], pre(foggy)['inputs'])
    torch.testing.assert_close(out['inputs'][:, 3:], pre(clear)['inputs'])
    # BGR -> RGB and normalisation per half: pixel (0, 0) of image 0
    raw = paired['inputs'][0][:, 0, 0].float()
    mean = torch.tensor([123.675, 116.28, 103.53])
    std = torch.tensor([58.395, 57.12, 57.375])
    torch.testing.assert_close(out['inputs'][0, :3, 0, 0],
                               (raw[[2, 1, 0]] - mean) / std)
    torch.testing.assert_close(out['inputs'][0, 3:, 0, 0],
                               (raw[[5, 4, 3]] - mean) / std)
    assert out['data_samples'][1].batch_input_shape == (64, 64)
    assert out['data_samples'][1].pad_shape == (64, 32)


def test_bad_input():
    with pytest.raises(ValueError, match='batch_augments'):
        MODELS.build(
            dict(make_preprocessor_cfg(),
                 batch_augments=[dict(type='BatchFixedSizePad', size=(8, 8))]))
    pre = MODELS.build(make_preprocessor_cfg())
    with pytest.raises(ValueError, match='3 channels or 6'):
        pre(demo_mm_inputs(1, [(4, 8, 8)]))
