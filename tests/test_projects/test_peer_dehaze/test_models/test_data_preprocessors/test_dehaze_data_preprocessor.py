"""CBNetDehazeDataPreprocessor in front of an MMDetection detector."""
import copy

import numpy as np
import pytest
import torch
from mmdet.registry import MODELS
from mmdet.testing import demo_mm_inputs
from mmengine.config import ConfigDict
from torch import nn

import cbnet_dehaze  # noqa: F401
from cbnet_dehaze.models.dehazers import BaseDehazer

MEAN, STD = [123.675, 116.28, 103.53], [58.395, 57.12, 57.375]
PLAIN = dict(type='DetDataPreprocessor', mean=MEAN, std=STD,
             bgr_to_rgb=True, pad_size_divisor=32, pad_mask=True)
#: the learned dehazer untrained: zero tail, so exactly the identity
IDENTITY = dict(type='CBNetAttentionDehazer', channels=8, num_blocks=1)


@MODELS.register_module(force=True)
class _DropRedDehazer(BaseDehazer):
    """Test dehazer: zeroes the R channel of its RGB input, scales by 0.5."""

    def __init__(self):
        super().__init__()
        self.scale = nn.Parameter(torch.tensor(0.5))

    def dehaze(self, img):
        return torch.cat([img[:, :1] * 0, img[:, 1:] * self.scale], 1)


def dehaze_cfg(dehaze=IDENTITY, **kwargs):
    return dict(PLAIN, type='CBNetDehazeDataPreprocessor', dehaze=dehaze,
                **kwargs)


def batch(sizes=((3, 37, 53), (3, 64, 30)), seed=0):
    torch.manual_seed(seed)
    return demo_mm_inputs(len(sizes), list(sizes), num_items=[2] * len(
        sizes), with_mask=True)


def test_identity_dehazer_equals_plain_preprocessor():
    plain, wrapped = MODELS.build(PLAIN), MODELS.build(dehaze_cfg())
    data = batch()
    ref, out = plain(copy.deepcopy(data), True), wrapped(data, True)
    assert out['inputs'].shape == ref['inputs'].shape == (2, 3, 64, 64)
    torch.testing.assert_close(out['inputs'], ref['inputs'], atol=1e-5,
                               rtol=0)
    for a, b in zip(out['data_samples'], ref['data_samples']):
        assert a.batch_input_shape == b.batch_input_shape
        assert a.pad_shape == b.pad_shape


def test_dehazer_sees_rgb_unpadded_and_output_is_renormalised():
    wrapped = MODELS.build(dehaze_cfg(dict(type='_DropRedDehazer')))
    data = batch()
    raw = [x.float() for x in data['inputs']]  # BGR 0-255
    out = wrapped(data)['inputs']
    mean, std = torch.tensor(MEAN), torch.tensor(STD)
    for i, img in enumerate(raw):
        h, w = img.shape[1:]
        rgb = img[[2, 1, 0]] / 255
        expected = torch.stack([rgb[0] * 0, rgb[1] * .5, rgb[2] * .5]) * 255
        expected = (expected - mean.view(3, 1, 1)) / std.view(3, 1, 1)
        torch.testing.assert_close(out[i, :, :h, :w], expected, atol=1e-4,
                                   rtol=0)
        # the padding keeps the pad value (0), normalised: not dehazed
        if h < 64:
            assert torch.all(out[i, :, h:, :] == 0)


def test_frozen_by_default_joint_on_request():
    frozen = MODELS.build(dehaze_cfg(dict(type='_DropRedDehazer')))
    frozen.train()
    assert not frozen.dehazer.training
    assert not frozen.dehazer.scale.requires_grad
    assert not frozen(batch(), True)['inputs'].requires_grad
    joint = MODELS.build(
        dehaze_cfg(dict(type='_DropRedDehazer'), train_dehazer=True))
    joint.train()
    assert joint.dehazer.training
    out = joint(batch(), True)['inputs']
    out.sum().backward()
    assert joint.dehazer.scale.grad is not None
    assert joint.dehazer.scale.grad.abs() > 0


def test_rgb_input_order_grey_and_rgba():
    # RGB input (rgb_to_bgr): no flip before the dehazer
    cfg = dehaze_cfg(dict(type='_DropRedDehazer'))
    cfg.update(bgr_to_rgb=False, rgb_to_bgr=True)
    pre = MODELS.build(cfg)
    assert pre.input_order == 'rgb'
    data = batch([(3, 16, 16)])
    out = pre(data)['inputs'][0, :, :16, :16]  # unpadded
    # channel 0 of the RGB input was zeroed; the output is BGR: channel 2
    assert torch.allclose(out[2], torch.full_like(out[2], -MEAN[2] / STD[2]))
    assert not torch.allclose(out[0], torch.full_like(out[0],
                                                      -MEAN[0] / STD[0]))
    grey = demo_mm_inputs(1, [(1, 20, 24)])
    assert MODELS.build(dehaze_cfg())(grey)['inputs'].shape == (1, 3, 32, 32)
    with pytest.raises(ValueError, match='RGBA'):
        MODELS.build(dehaze_cfg())(demo_mm_inputs(1, [(4, 20, 24)]))
    with pytest.raises(ValueError, match='input_order'):
        MODELS.build(dehaze_cfg(input_order='yuv'))


def test_detector_output_unchanged_with_identity_dehazer(
        make_detector_cfg):
    torch.manual_seed(0)
    det_cfg = ConfigDict(make_detector_cfg())
    plain = MODELS.build(dict(det_cfg, data_preprocessor=PLAIN))
    plain.init_weights()
    wrapped = MODELS.build(dict(det_cfg, data_preprocessor=dehaze_cfg()))
    missing, unexpected = wrapped.load_state_dict(plain.state_dict(),
                                                  strict=False)
    assert not unexpected
    assert all(k.startswith('data_preprocessor.dehazer.') for k in missing)
    plain.eval(), wrapped.eval()
    data = batch(((3, 96, 128), (3, 80, 112)), seed=1)
    with torch.no_grad():
        res_p = plain.test_step(copy.deepcopy(data))
        res_w = wrapped.test_step(data)
    for a, b in zip(res_w, res_p):
        pa, pb = a.pred_instances, b.pred_instances
        assert len(pa) == len(pb) > 0
        torch.testing.assert_close(pa.bboxes, pb.bboxes, atol=1e-2, rtol=0)
        torch.testing.assert_close(pa.scores, pb.scores, atol=1e-4, rtol=0)
        torch.testing.assert_close(pa.labels, pb.labels)
    # the loss of a training step too
    losses = []
    for model in (plain, wrapped):
        inputs = model.data_preprocessor(batch(seed=2), True)
        torch.manual_seed(3)  # same RPN / RoI sampling
        np.random.seed(3)
        with torch.no_grad():
            losses.append(model(**inputs, mode='loss'))
    loss_p, loss_w = losses
    for k in loss_p:
        if 'loss' in k:
            torch.testing.assert_close(
                sum(loss_w[k]) if isinstance(loss_w[k], list) else loss_w[k],
                sum(loss_p[k]) if isinstance(loss_p[k], list) else loss_p[k],
                atol=1e-4, rtol=1e-4)


def saved_dehazer(tmp_path):
    """A random dehazer and its weights saved as a dehazer checkpoint."""
    src = MODELS.build(IDENTITY)
    for p in src.parameters():
        nn.init.normal_(p, std=0.1)
    path = tmp_path / 'dehazer.pth'
    torch.save(dict(state_dict={'dehazer.' + k: v for k, v in
                                src.state_dict().items()}), path)
    return src, path


def test_dehazer_checkpoint_loads_on_its_own(tmp_path):
    src, path = saved_dehazer(tmp_path)
    pre = MODELS.build(dehaze_cfg(dehaze_checkpoint=str(path)))
    pre.init_weights()
    for k, v in src.state_dict().items():
        torch.testing.assert_close(pre.dehazer.state_dict()[k], v)
    wrong = MODELS.build(dehaze_cfg(dict(IDENTITY, channels=16),
                                    dehaze_checkpoint=str(path)))
    with pytest.raises(RuntimeError, match='mismatched'):
        wrong.init_weights()


def test_missing_dehazer_checkpoint_builds_and_fails_at_init(tmp_path):
    """The file is needed by init_weights (training), not to build: a full
    detector checkpoint then provides the dehazer for inference."""
    missing = str(tmp_path / 'absent.pth')
    pre = MODELS.build(dehaze_cfg(dehaze_checkpoint=missing))
    with pytest.raises(FileNotFoundError, match='absent.pth'):
        pre.init_weights()


def test_detector_init_weights_loads_the_dehazer_checkpoint(
        tmp_path, make_detector_cfg):
    """MMEngine reaches the preprocessor through the detector's
    init_weights, as the Runner calls it before training."""
    src, path = saved_dehazer(tmp_path)
    model = MODELS.build(dict(
        ConfigDict(make_detector_cfg()),
        data_preprocessor=dehaze_cfg(dehaze_checkpoint=str(path))))
    model.init_weights()
    for k, v in src.state_dict().items():
        torch.testing.assert_close(
            model.data_preprocessor.dehazer.state_dict()[k], v)
