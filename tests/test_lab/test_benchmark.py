"""The benchmarks' helpers (cbnet_lab/benchmark.py): seeded weightless
builds (configs without pretrained weights are config_edits', tested in
tests/test_lab/test_config_edits.py), FLOPs against hand-counted
references, the fixed proposal set and its context, the input size after a
test pipeline, batches with a photo in (the timing and memory helpers it
imports: tests/test_cbnet_tools/test_measure.py; the command line:
tests/test_tools/test_benchmark_cli.py)."""
import os.path as osp

import pytest
import torch
from tool_helpers import load_tool

import cbnet_lab.benchmark as benchmark_utils
from cbnet_lab.benchmark import count_flops
from cbnet_lab.config_edits import load_benchmark_cfg

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
#: models of benchmark.py's --suite edge: the edge model and a server one
EDGE = 'edge_fcos-lite_320'
SERVER = 'server_cascade-rcnn'


def test_count_flops_conv_reference():
    """A 3x3 conv with 8 out channels on 3x10x10 (valid): 8*3*9*64 MACs."""

    class Tiny(torch.nn.Module):

        def __init__(self):
            super().__init__()
            self.conv = torch.nn.Conv2d(3, 8, 3)

        def extract_feat(self, x):
            return self.conv(x)

        def forward(self, inputs, data_samples=None, mode='predict'):
            return self.extract_feat(inputs)

    data = dict(inputs=torch.randn(1, 3, 10, 10), data_samples=None)
    flops = count_flops(Tiny(), data)
    assert flops['features'] == pytest.approx(8 * 3 * 9 * 64 / 1e9)
    assert flops['predict'] == flops['features']


def test_count_flops_counts_cpu_attention():
    """MiT's attention runs PyTorch's fused CPU kernel, which
    FlopCounterMode alone counts as zero: its two products, written out,
    are the reference (QK^T: b*h*L*S*E, AV: b*h*L*S*Ev multiply-adds)."""
    b, h, L, S, E = 1, 2, 256, 64, 32

    class Attn(torch.nn.Module):

        def extract_feat(self, q):
            k = q[:, :, :S]
            bias = torch.zeros(b, h, L, S)
            return torch.nn.functional.scaled_dot_product_attention(
                q, k, k, attn_mask=bias)

        def forward(self, inputs, data_samples=None, mode='predict'):
            return self.extract_feat(inputs)

    data = dict(inputs=torch.randn(b, h, L, E), data_samples=None)
    flops = count_flops(Attn(), data)
    assert flops['features'] == pytest.approx(2 * b * h * L * S * E / 1e9)


def test_build_detector_is_seeded():
    """Every run measures the same random model (proposals, and so the RoI
    heads' cost, depend on the weights)."""
    from cbnet_lab.benchmark import build_detector
    cfg = load_benchmark_cfg(
        osp.join(ROOT, 'configs', 'baselines',
                 'yolox_s_8xb8-300e_cityscapes.py'))
    torch.manual_seed(123)
    a = build_detector(cfg).state_dict()
    b = build_detector(cfg).state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    c = build_detector(cfg, seed=1).state_dict()
    assert not all(torch.equal(a[k], c[k]) for k in a)


def test_realistic_proposals_distribution():
    from cbnet_lab.benchmark import realistic_proposals
    boxes = realistic_proposals((512, 1024), num=4000)
    assert boxes.shape == (4000, 4)
    assert (boxes[:, 0] >= 0).all() and (boxes[:, 2] <= 1024).all()
    assert (boxes[:, 1] >= 0).all() and (boxes[:, 3] <= 512).all()
    assert (boxes[:, 2] >= boxes[:, 0]).all()
    # scale log-uniform in [8, 256] (median 45 px); the boxes that do not
    # touch the border lean small (large ones are clipped more often)
    inner = ((boxes[:, 0] > 0) & (boxes[:, 1] > 0) & (boxes[:, 2] < 1024) &
             (boxes[:, 3] < 512))
    wh = (boxes[inner, 2:] - boxes[inner, :2])
    scale = (wh[:, 0] * wh[:, 1]).sqrt()
    assert 7.9 < scale.min() and scale.max() < 256.1
    assert 28 < scale.median() < 45
    # scaled with the image height, same seed -> same boxes
    big = realistic_proposals((1024, 2048), num=4000)
    torch.testing.assert_close(big[inner], boxes[inner] * 2)
    assert torch.equal(realistic_proposals((512, 1024), num=4000), boxes)
    with pytest.raises(ValueError, match='min_side'):
        realistic_proposals((64, 64), min_side=0)


def test_fixed_proposals_feed_the_roi_head_and_undo():
    """Inside the context the RPN still runs but the RoI head sees the
    fixed boxes; afterwards the class's method is back."""
    from cbnet_lab.benchmark import (FixedProposals, build_detector,
                                     make_batch,
                                     preprocess)
    cfg = load_benchmark_cfg(osp.join(
        ROOT, 'configs', 'demo',
        'mask-rcnn_mit-b0_fpn_1xb4-demo_cityscapes-like.py'))
    model = build_detector(cfg).eval()
    data = preprocess(model, make_batch(1, (64, 128), 2), False)
    seen, calls = [], []
    roi_predict = model.roi_head.predict
    rpn_predict = model.rpn_head.predict

    def spy_roi(x, proposals, *args, **kwargs):
        seen.append(proposals[0].bboxes.clone())
        return roi_predict(x, proposals, *args, **kwargs)

    def spy_rpn(*args, **kwargs):
        calls.append(1)
        return rpn_predict(*args, **kwargs)

    model.roi_head.predict = spy_roi
    model.rpn_head.predict = spy_rpn
    with torch.no_grad(), FixedProposals(model, num=50):
        model(**data, mode='predict')
    assert calls == [1]  # the RPN's cost is still measured
    full = benchmark_utils.realistic_proposals((64, 128), num=1000)
    # the top 50 of the one 1000-box set
    torch.testing.assert_close(seen[0], full[:50])
    # by default as many as the RPN keeps at test time
    keep = model.rpn_head.test_cfg.max_per_img
    assert keep < 1000
    with torch.no_grad(), FixedProposals(model):
        model(**data, mode='predict')
    torch.testing.assert_close(seen[1], full[:keep])
    assert model.rpn_head.predict is spy_rpn  # put back
    del model.rpn_head.predict
    with FixedProposals(model):
        pass
    assert 'predict' not in vars(model.rpn_head)


def test_pipeline_input_size_follows_the_test_resize():
    from mmengine.config import Config

    from cbnet_lab.benchmark import pipeline_input_size
    bench_script = load_tool('analysis_tools/benchmark.py')

    def cfg_of(name):
        return Config.fromfile(osp.join(ROOT, bench_script.MODELS[name]))

    # keep_ratio into (320, 240) / (640, 480): the scale is the smaller of
    # the two ratios, sizes rounded as MMCV rounds (int(x * s + 0.5))
    assert pipeline_input_size(cfg_of(EDGE), (360, 640)) == (180, 320)
    assert pipeline_input_size(cfg_of(EDGE), (675, 1280)) == (169, 320)
    assert pipeline_input_size(cfg_of(SERVER), (360, 640)) == (360, 640)
    assert pipeline_input_size(cfg_of(SERVER), (45, 80)) == (360, 640)

    def with_pipeline(*resizes):
        return Config(dict(test_dataloader=dict(dataset=dict(pipeline=[
            dict(type='LoadImageFromFile'), *resizes,
            dict(type='PackDetInputs')]))))

    assert pipeline_input_size(with_pipeline(), (50, 70)) == (50, 70)
    assert pipeline_input_size(with_pipeline(dict(
        type='Resize', scale=(64, 32), keep_ratio=False)), (50, 70)) == \
        (32, 64)
    assert pipeline_input_size(with_pipeline(dict(
        type='Resize', scale_factor=0.5)), (50, 70)) == (25, 35)
    with pytest.raises(ValueError, match='only one MMDet Resize'):
        pipeline_input_size(with_pipeline(
            dict(type='Resize', scale=(64, 32)),
            dict(type='Resize', scale=(32, 16))), (50, 70))
    with pytest.raises(ValueError, match='only one MMDet Resize'):
        pipeline_input_size(with_pipeline(
            dict(type='RandomResize', scale=(64, 32))), (50, 70))
    with pytest.raises(ValueError, match='no test pipeline'):
        pipeline_input_size(Config(dict(model=dict())), (50, 70))


def test_make_batch_puts_the_photo_in_at_the_size():
    import cv2
    import numpy as np

    from cbnet_lab.benchmark import make_batch
    photo = np.random.RandomState(0).randint(
        0, 256, (67, 128, 3), dtype=np.uint8)
    batch = make_batch(2, (36, 64), num_items=2, with_mask=False,
                       image=photo)
    expected = cv2.resize(photo, (64, 36), interpolation=cv2.INTER_LINEAR)
    for img in batch['inputs']:
        assert img.dtype == torch.uint8 and img.shape == (3, 36, 64)
        assert torch.equal(img, torch.from_numpy(expected).permute(2, 0, 1))
    assert batch['data_samples'][0].metainfo['img_shape'] == (36, 64)
    with pytest.raises(ValueError, match='H x W x 3 uint8'):
        make_batch(1, (36, 64), image=photo[..., 0])
    with pytest.raises(ValueError, match='size must be'):
        make_batch(1, (0, 64), image=photo)
