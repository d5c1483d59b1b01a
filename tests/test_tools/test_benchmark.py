"""Smoke test of tools/analysis_tools/benchmark.py (one small model, one
repeat, tiny input) and unit tests of its helpers."""
import json
import os
import os.path as osp
import subprocess
import sys
import time

import pytest
import torch

from tool_helpers import load_tool

import cbnet_lab.benchmark as benchmark_utils
from cbnet_lab.benchmark import PeakMemory, count_flops, summarize
from cbnet_lab.config_edits import load_benchmark_cfg, strip_pretrained

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
SCRIPT = osp.join(ROOT, 'tools', 'analysis_tools', 'benchmark.py')


def test_strip_pretrained_any_depth():
    cfg = dict(
        backbone=dict(
            type='X', pretrained='a.pth',
            init_cfg=dict(type='Pretrained', checkpoint='a.pth')),
        neck=dict(init_cfg=[dict(type='Xavier'),
                            dict(type='Pretrained', checkpoint='b')]),
        head=dict(init_cfg=dict(type='Normal', std=0.01)))
    out = strip_pretrained(cfg)
    assert out['backbone'] == dict(type='X', init_cfg=None)
    assert out['neck']['init_cfg'] is None
    assert out['head'] == cfg['head']  # other inits untouched
    assert cfg['backbone']['pretrained'] == 'a.pth'  # input not modified


def test_summarize_matches_statistics():
    s = summarize([4.0, 1.0, 3.0, 2.0, 5.0])
    assert s == dict(median=3.0, min=1.0, max=5.0, iqr=2.0,
                     p95=pytest.approx(4.8))
    times = [0.3, 7.5, 1.0, 2.0, 2.5, 9.0, 0.1, 4.0, 3.3]
    import numpy as np
    assert summarize(times)['p95'] == pytest.approx(
        np.percentile(times, 95))
    assert summarize([2.0])['iqr'] == 0.0
    assert summarize([2.0])['p95'] == 2.0
    with pytest.raises(ValueError, match='no durations'):
        summarize([])


def test_time_alternately_alternates_after_warm_up_rounds():
    order, rounds = [], []
    calls = {n: (lambda n=n: order.append(n) or len(order)) for n in 'ab'}
    times = benchmark_utils.time_alternately(
        calls, repeats=3, warmup=2,
        on_round=lambda i, m: rounds.append((i, len(m['a']))))
    assert order == list('ab' * 5)  # 2 warm-up rounds, then 3 timed
    assert [len(v) for v in times.values()] == [3, 3]
    assert all(t >= 0 for v in times.values() for t in v)
    assert rounds == [(0, 1), (1, 2), (2, 3)]
    # calls that time themselves: their return values are kept
    own = benchmark_utils.time_alternately(calls, 2, 0, self_timed=True)
    assert own == dict(a=[11, 13], b=[12, 14])


def test_peak_memory_sees_a_large_allocation():
    if not osp.exists('/proc/self/statm'):
        pytest.skip('needs Linux /proc')
    with PeakMemory('cpu') as mem:
        x = torch.ones(64, 2**20 // 4 * 4)  # 256 MiB of float32, touched
        del x
    assert mem.method in ('vmhwm', 'sampled')
    assert mem.peak is not None
    if mem.method == 'vmhwm':
        assert 200 < mem.peak < 400
    else:  # polling is a lower bound: a short peak can fall between polls
        assert mem.peak < 400


def test_peak_memory_sampling_fallback(monkeypatch):
    """Where the kernel does not keep VmHWM, a polling thread measures."""
    if not osp.exists('/proc/self/statm'):
        pytest.skip('needs Linux /proc')
    monkeypatch.setattr(benchmark_utils, '_HWM_RESETS', False)
    with PeakMemory('cpu', interval=0.001) as mem:
        x = torch.ones(64, 2**20 // 4 * 4)  # 256 MiB of float32, touched
        time.sleep(0.05)  # held for 50 polling periods
        del x
    assert mem.method == 'sampled'
    assert 200 < mem.peak < 400
    with PeakMemory('cpu', interval=0.001) as idle:
        pass
    assert idle.method == 'sampled' and abs(idle.peak) < 50


def test_peak_memory_is_not_hidden_by_memory_the_allocator_cached():
    """Memory freed before the block (kept by glibc's heap at the steady
    thresholds) must not absorb the block's allocations."""
    if not osp.exists('/proc/self/statm') or \
            not benchmark_utils.set_malloc_thresholds():
        pytest.skip('needs Linux /proc and glibc')
    chunks = [torch.ones(2**21) for _ in range(16)]  # 16 x 8 MiB, heap
    del chunks  # freed into the heap (below the 32 MiB mmap threshold)
    with PeakMemory('cpu') as mem:
        chunks = [torch.ones(2**21) for _ in range(16)]
        time.sleep(0.02)  # for the polling fallback
        del chunks
    assert 100 < mem.peak < 200


def test_hwm_probe_is_cached_and_boolean():
    first = benchmark_utils.hwm_reset_works()
    assert isinstance(first, bool)
    assert benchmark_utils.hwm_reset_works() is first


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


def test_bad_thread_count_is_a_clear_error():
    out = subprocess.run(
        [sys.executable, SCRIPT, '--threads', '0'],
        capture_output=True, text=True, cwd=ROOT,
        env=dict(os.environ, PYTHONPATH=ROOT))
    assert out.returncode != 0 and '--threads must be at least 1' in (
        out.stderr)


def test_unknown_model_is_a_clear_error():
    out = subprocess.run(
        [sys.executable, SCRIPT, '--models', 'nope'],
        capture_output=True, text=True, cwd=ROOT,
        env=dict(os.environ, PYTHONPATH=ROOT))
    assert out.returncode != 0 and "unknown model 'nope'" in out.stderr


@pytest.mark.slow
def test_benchmark_script_smoke(tmp_path):
    """YOLOX-S, 64x128, one repeat: JSON, markdown and plot written."""
    cmd = [
        sys.executable, SCRIPT, '--models', 'yolox_s', '--size', '64', '128',
        '--batch-sizes', '1', '--repeats', '1', '--warmup', '0',
        '--scale-models', 'yolox_s', '--scale-sizes', '64x128',
        '--scale-items', '2', '--threads', '1', '--out-dir', str(tmp_path)
    ]
    subprocess.run(cmd, check=True, capture_output=True, cwd=ROOT,
                   env=dict(os.environ, PYTHONPATH=ROOT))
    with open(tmp_path / 'benchmark.json') as f:
        res = json.load(f)
    r = res['results']['yolox_s']
    assert 8.5 < r['params_m'] < 9.5  # YOLOX-S with 8 classes: 8.9M
    assert r['gflops']['features'] > 0
    assert r['gflops']['predict'] >= r['gflops']['features']
    assert set(r['inference']) == {'1'}
    assert r['inference']['1']['seconds']['median'] > 0
    assert r['train_step']['seconds']['median'] > 0
    meta = res['meta']
    assert meta['size'] == [64, 128]
    assert meta['machine']['threads'] == 1
    assert meta['machine']['cpu_count'] == os.cpu_count()
    assert meta['machine']['torch'] == torch.__version__
    assert meta['machine']['mmdet'] and meta['machine']['platform']
    if hasattr(os, 'getloadavg'):
        assert len(meta['load_start']) == len(meta['load_end']) == 3
    assert '--threads 1' in meta['command'] and meta['date']
    assert res['scaling']['items']['yolox_s'][0]['num_items'] == 2
    md = (tmp_path / 'benchmark.md').read_text()
    assert '| yolox_s | 8.9 |' in md
    assert 'torch 1,' in md and 'load average' in md
    assert (tmp_path / 'scaling.png').stat().st_size > 1000


def test_benchmark_backbone_smoke(tmp_path):
    """MiT-B0 ope vs cspe at 64x64, one run: times and peak memory."""
    out = tmp_path / 'backbone.json'
    cmd = [
        sys.executable,
        osp.join(ROOT, 'tools', 'analysis_tools', 'benchmark_backbone.py'),
        '--archs', 'b0', '--size', '64', '64', '--runs', '1', '--threads',
        '1', '--out', str(out)
    ]
    proc = subprocess.run(cmd, check=True, capture_output=True, text=True,
                          cwd=ROOT, env=dict(os.environ, PYTHONPATH=ROOT))
    res = json.loads(out.read_text())['results']
    pairs = [(r['arch'], r['pos']) for r in res]
    assert pairs == [('b0', 'ope'), ('b0', 'cspe')]
    for r in res:
        assert r['time_s'] > 0 and len(r['times_s']) == 1
        assert r['peak_mib'] is not None and r['peak_mib'] >= 0
    assert '| b0 | cspe |' in proc.stdout


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
                                     make_batch, preprocess)
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


def test_model_cfg_overrides_one_model_only(capsys):
    bench_script = load_tool('analysis_tools/benchmark.py')
    args = bench_script.parse_args([
        '--models', 'paper=cbnet_mit-b0', 'cbnet_mit-b0', '--model-cfg',
        'paper', 'model.neck.fine_path=cells', '--train-batch-size', '2'
    ])
    assert args.configs['paper'] == args.configs['cbnet_mit-b0']
    assert args.overrides == {'paper': {'model.neck.fine_path': 'cells'}}
    assert args.train_batch_size == 2
    for bad, match in ((['--model-cfg', 'nope', 'a=1'], 'not one of'),
                       (['--model-cfg', 'cbnet_mit-b0', 'a'], 'KEY=VALUE'),
                       (['--train-batch-size', '0'], 'at least 1')):
        with pytest.raises(SystemExit):
            bench_script.parse_args(['--models', 'cbnet_mit-b0'] + bad)
        assert match in capsys.readouterr().err


def test_results_are_written_after_every_phase(tmp_path):
    """A run killed later (e.g. out of memory in a training step, or a time
    limit between two inference rounds) keeps what it measured: every
    timed inference round and each phase checkpoints the results."""
    bench_script = load_tool('analysis_tools/benchmark.py')
    args = bench_script.parse_args([
        '--models', 'yolox_s', '--size', '64', '64', '--batch-sizes', '1',
        '--repeats', '2', '--warmup', '0', '--no-flops', '--scale-models',
        'yolox_s', '--scale-sizes', '32x32', '--scale-items', '--threads',
        '1', '--out-dir', str(tmp_path)
    ])
    seen = []

    def checkpoint(res, sca):
        times = res['yolox_s'].get('inference', {}).get('1', {}).get('times')
        seen.append((sorted(res['yolox_s']), sorted(sca['sizes']),
                     len(times or [])))

    bench_script.run(args, checkpoint)
    # inference: two rounds, the finished phase; the same for training;
    # scaling
    assert [s[2] for s in seen] == [1, 2, 2, 2, 2, 2, 2]
    assert [s[1] for s in seen] == [[]] * 6 + [['yolox_s']]
    assert all('train_step' not in s[0] for s in seen[:3])
    assert all('train_step' in s[0] for s in seen[3:])


def test_no_infer_measures_training_only(tmp_path):
    bench_script = load_tool('analysis_tools/benchmark.py')
    bench_script.main([
        '--models', 'yolox_s', '--size', '64', '64', '--repeats', '1',
        '--warmup', '0', '--no-flops', '--no-infer', '--scale-models',
        '--scale-items', '--threads', '1', '--out-dir', str(tmp_path)
    ])
    with open(tmp_path / 'benchmark.json') as f:
        results = json.load(f)['results']
    assert 'inference' not in results['yolox_s']
    assert len(results['yolox_s']['train_step']['times']) == 1
    assert '| yolox_s |' in (tmp_path / 'benchmark.md').read_text()


def test_test_time_proposal_count_is_recorded(tmp_path):
    """Each two-stage model's RoI heads get as many fixed proposals as its
    RPN keeps at test time, and the tables say how many."""
    bench_script = load_tool('analysis_tools/benchmark.py')
    args = bench_script.parse_args([
        '--models', 'cbnet_mit-b0', 'k1000=cbnet_mit-b0', '--model-cfg',
        'k1000', 'model.test_cfg.rpn.max_per_img=1000', '--size', '64',
        '64', '--batch-sizes', '1', '--repeats', '1', '--warmup', '0',
        '--no-flops', '--no-train', '--scale-models', '--scale-items',
        '--threads', '1', '--out-dir', str(tmp_path)
    ])
    results, _ = bench_script.run(args, lambda res, sca: None)
    cfg = load_benchmark_cfg(
        osp.join(ROOT, args.configs['cbnet_mit-b0']))
    keep = cfg.model.test_cfg.rpn.max_per_img
    assert keep < 1000
    assert results['cbnet_mit-b0']['test_proposals'] == keep
    assert results['k1000']['test_proposals'] == 1000
    bench_script.main([
        '--models', 'yolox_s', '--size', '64', '64', '--batch-sizes', '1',
        '--repeats', '1', '--warmup', '0', '--no-flops', '--no-train',
        '--scale-models', '--scale-items', '--threads', '1', '--out-dir',
        str(tmp_path / 'single')
    ])
    # a single-stage model has no proposals: no such line
    assert 'proposals per image at test time' not in (
        tmp_path / 'single' / 'benchmark.md').read_text()


def test_scaling_only_run_prints_no_empty_model_table(tmp_path):
    bench_script = load_tool('analysis_tools/benchmark.py')
    bench_script.main([
        '--models', 'yolox_s', '--size', '32', '32', '--repeats', '1',
        '--warmup', '0', '--no-flops', '--no-infer', '--no-train',
        '--scale-models', 'yolox_s', '--scale-sizes', '32x32',
        '--scale-items', '--threads', '1', '--out-dir', str(tmp_path)
    ])
    text = (tmp_path / 'benchmark.md').read_text()
    assert 'params (M)' not in text
    assert '| yolox_s | 32x32 |' in text


# --suite edge: the edge model next to the server models on
# camera frames each model gets resized as its test pipeline resizes them

EDGE = 'edge_fcos-lite_320'
SERVER = 'server_cascade-rcnn'


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


def test_edge_suite_defaults_and_overrides():
    bench_script = load_tool('analysis_tools/benchmark.py')
    args = bench_script.parse_args(['--suite', 'edge'])
    assert list(args.configs) == [EDGE, 'fcos-lite_640', SERVER,
                                  'server_cbnet-revised']
    assert args.size == [360, 640] and args.config_resize
    assert args.threads == 1 and args.batch_sizes == [1]
    assert args.no_train and args.reference == EDGE
    assert args.scale_models == [] and args.scale_sizes == []
    # the command line wins over the suite
    args = bench_script.parse_args(['--suite', 'edge', '--size', '90', '160',
                                    '--models', EDGE, '--repeats', '3'])
    assert args.size == [90, 160] and list(args.configs) == [EDGE]
    assert args.repeats == 3 and args.warmup == 2
    # without the suite, nothing changes
    plain = bench_script.parse_args([])
    assert plain.size == [128, 256] and not plain.config_resize
    assert plain.reference == 'cascade-mask-rcnn_swin-s'


@pytest.mark.parametrize('argv, match', [
    (['--size', '0', '640'], '--size must be two positive'),
    (['--size', '360x640', '640'], 'invalid int value'),
    (['--size', '360'], 'expected 2 arguments'),
    (['--models', 'x=/no/such/config.py'], "config of 'x' not found"),
    (['--checkpoint', 'nope', __file__], '--checkpoint nope: not one of'),
    (['--checkpoint', EDGE, '/no/such.pth'], 'no such file /no/such.pth'),
    (['--suite', 'nope'], "invalid choice: 'nope'"),
])
def test_edge_suite_bad_arguments_are_clear_errors(argv, match, capsys):
    bench_script = load_tool('analysis_tools/benchmark.py')
    with pytest.raises(SystemExit):
        bench_script.parse_args(['--suite', 'edge'] + argv)
    assert match in capsys.readouterr().err


def test_a_missing_or_unreadable_image_is_an_error_before_any_build(
        tmp_path):
    bench_script = load_tool('analysis_tools/benchmark.py')
    bad = tmp_path / 'photo.jpg'
    bad.write_text('not a jpeg')
    args = bench_script.parse_args(['--suite', 'edge', '--image', str(bad),
                                    '--out-dir', str(tmp_path / 'out')])
    with pytest.raises(ValueError, match='not readable as an image'):
        bench_script.run(args)
    args.image = str(tmp_path / 'none.jpg')
    with pytest.raises(FileNotFoundError, match='none.jpg: no such file'):
        bench_script.run(args)


def test_checkpoint_loads_strictly(tmp_path):
    from cbnet_lab.benchmark import build_detector
    from cbnet_lab.model_benchmark import Bench
    bench_script = load_tool('analysis_tools/benchmark.py')
    trained = build_detector(load_benchmark_cfg(
        osp.join(ROOT, bench_script.MODELS[EDGE])), seed=5).state_dict()
    torch.save(dict(state_dict=trained), tmp_path / 'edge.pth')
    args = bench_script.parse_args([
        '--suite', 'edge', '--models', EDGE, '--checkpoint', EDGE,
        str(tmp_path / 'edge.pth')])
    loaded = Bench(args).models[EDGE].state_dict()
    assert all(torch.equal(loaded[k], v) for k, v in trained.items())
    # a checkpoint of another model: an error, not a half-loaded model
    del trained['bbox_head.conv_cls.weight']
    torch.save(dict(state_dict=trained), tmp_path / 'other.pth')
    args = bench_script.parse_args([
        '--suite', 'edge', '--models', EDGE, '--checkpoint', EDGE,
        str(tmp_path / 'other.pth')])
    with pytest.raises(RuntimeError, match='conv_cls.weight'):
        Bench(args)


def test_edge_suite_end_to_end_on_a_tiny_frame(tmp_path):
    """Two models on a 45x80 photo: each gets the frame as its pipeline
    resizes it, the record has the timing, memory and machine fields."""
    import cv2
    import numpy as np
    bench_script = load_tool('analysis_tools/benchmark.py')
    photo = np.random.RandomState(1).randint(
        0, 256, (90, 160, 3), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / 'frame.png'), photo)
    out = tmp_path / 'out'
    bench_script.main([
        '--suite', 'edge', '--models', EDGE, SERVER, '--size', '45', '80',
        '--repeats', '2', '--warmup', '1', '--no-flops', '--model-cfg',
        SERVER, 'model.test_cfg.rpn.max_per_img=20', '--image',
        str(tmp_path / 'frame.png'), '--out-dir', str(out)])
    with open(out / 'benchmark.json') as f:
        record = json.load(f)
    meta, results = record['meta'], record['results']
    assert meta['suite'] == 'edge' and meta['config_resize']
    assert meta['size'] == [45, 80] and meta['image'].endswith('frame.png')
    assert meta['machine']['threads'] == 1 and meta['reference'] == EDGE
    assert len(meta['load_start']) == 3 and meta['date'] and not \
        meta['partial']
    assert list(results) == [EDGE, SERVER]
    assert results[EDGE]['input_size'] == [180, 320]
    assert results[SERVER]['input_size'] == [360, 640]
    assert results[SERVER]['test_proposals'] == 20
    for r in results.values():
        inf = r['inference']['1']
        assert len(inf['times']) == len(inf['cpu_times']) == 2
        s = inf['seconds']
        assert 0 < s['min'] <= s['median'] <= s['p95'] <= s['max']
        assert inf['images_per_s'] == pytest.approx(1 / s['median'])
        assert 0 < inf['cpu_seconds']['median']
        assert inf['peak_mib'] is None or inf['peak_mib'] >= 0
        assert r['weights_mib'] > 0 and 'train_step' not in r
    md = (out / 'benchmark.md').read_text()
    assert f'| {EDGE} |' in md and '| 180x320 |' in md
    assert 'latency / ' + EDGE in md and 'load average' in md
    assert 'frame.png' in md
    assert md.startswith('Input 45x80') and ', random weights;' in md
    # the header says which models had trained weights
    from cbnet_lab.model_benchmark import markdown
    results[EDGE]['checkpoint'] = 'edge.pth'
    head = markdown(meta, results, record['scaling']).splitlines()[0]
    assert f'trained weights for {EDGE} (checkpoints below), random for ' \
        'the others;' in head
    results[SERVER]['checkpoint'] = 'server.pth'
    head = markdown(meta, results, record['scaling']).splitlines()[0]
    assert 'trained weights (checkpoints below);' in head


def test_scaling_plot_has_a_panel_per_measurement_only(tmp_path):
    """A run that timed only input sizes gets one panel (an empty
    'training vs instances' panel was drawn before); nothing measured is
    an error."""
    import cv2

    from cbnet_lab.model_benchmark import plot
    sizes = {'m': [dict(size=[64, 128], seconds=0.1),
                   dict(size=[128, 256], seconds=0.3)]}
    items = {'m': [dict(num_items=1, seconds=0.2),
                   dict(num_items=8, seconds=0.5)]}
    widths = {}
    for name, scaling in (('one', dict(sizes=sizes, items={})),
                          ('two', dict(sizes=sizes, items=items))):
        path = str(tmp_path / f'{name}.png')
        plot(scaling, path)
        widths[name] = cv2.imread(path).shape[1]
    assert widths == {'one': 500, 'two': 1000}  # 5 inches a panel, 100 dpi
    with pytest.raises(ValueError, match='no scaling measurement'):
        plot(dict(sizes={}, items={}), str(tmp_path / 'none.png'))
