"""tools/analysis_tools/benchmark.py: smoke tests (one small model, one
repeat, tiny input), its arguments and records, the edge suite end to end
(and benchmark_backbone.py's smoke test). The helpers' own tests:
tests/test_lab/test_benchmark.py, tests/test_lab/test_model_benchmark.py,
tests/test_cbnet_tools/test_measure.py."""
import json
import os
import os.path as osp
import subprocess
import sys

import pytest
import torch

from tool_helpers import load_tool

from cbnet_lab.config_edits import load_benchmark_cfg

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
SCRIPT = osp.join(ROOT, 'tools', 'analysis_tools', 'benchmark.py')


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
