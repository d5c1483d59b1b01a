"""The Ray Serve model server, end to end on 127.0.0.1.

One server (projects/edge_serving/tools/serve.py, the demo model with a
seeded random checkpoint) serves the module; the reference for its answers
is the same checkpoint run in this process through ``Predictor``
(``DetInferencer``).
The last test kills the server under the router.
"""
import glob
import json
import os
import os.path as osp
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
import pycocotools.mask as mask_util
import pytest
import requests
import torch
from mmdet.datasets import CityscapesDataset
from mmdet.registry import MODELS
from mmengine.config import Config
from mmengine.registry import init_default_scope
from tool_helpers import load_tool

from cbnet_serving.predictor import Predictor
from cbnet_serving.router import EdgeRouter, RouterConfig

pytestmark = pytest.mark.slow

pytest.importorskip('ray.serve', reason='the serve extra (tools/install.sh '
                    'installs it)')

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.dirname(
    osp.abspath(__file__)))))
TOOLS = osp.join(ROOT, 'projects', 'edge_serving', 'tools')
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
START_TIMEOUT_S = 150


@pytest.fixture(scope='module')
def demo_ckpt(tmp_path_factory):
    tmp = tmp_path_factory.mktemp('serve')
    init_default_scope('mmdet')
    torch.manual_seed(0)
    model = MODELS.build(Config.fromfile(DEMO).model)
    model.init_weights()
    ckpt = str(tmp / 'demo.pth')
    torch.save(dict(state_dict=model.state_dict(),
                    meta=dict(dataset_meta=dict(CityscapesDataset.METAINFO))),
               ckpt)
    return ckpt


def start_server(args, log):
    """serve.py with ``args`` (config, checkpoint...) on a free port of
    127.0.0.1, its output into the open file ``log``; returns the process
    and its URL once /health answers (fails the test with the log's tail
    when it does not)."""
    import socket
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        port = sock.getsockname()[1]
    env = dict(os.environ, OMP_NUM_THREADS='1', RAY_USAGE_STATS_ENABLED='0')
    proc = subprocess.Popen(
        [sys.executable, osp.join(TOOLS, 'serve.py'), *args, '--port',
         str(port), '--num-cpus', '1'],
        cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT,
        start_new_session=True)
    url = f'http://127.0.0.1:{port}'
    deadline = time.monotonic() + START_TIMEOUT_S
    while True:
        try:
            if requests.get(url + '/health', timeout=2).status_code == 200:
                return proc, url
        except requests.RequestException:
            pass
        if proc.poll() is not None or time.monotonic() > deadline:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:  # it died: its log says why
                pass
            log.seek(0)
            pytest.fail('server did not start:\n' + log.read()[-3000:])
        time.sleep(0.5)


def stop_group(proc):
    """SIGTERM, then SIGKILL, to the server's whole process group, also
    when the leader is gone (a test killed it): Ray's workers may outlive
    it; a group already gone is no error."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(proc.pid, sig)
            proc.wait(30)
            break
        except ProcessLookupError:
            break
        except subprocess.TimeoutExpired:
            pass  # SIGKILL next


@pytest.fixture(scope='module')
def server(demo_ckpt, tmp_path_factory):
    log = open(tmp_path_factory.mktemp('serve_log') / 'server.log', 'w+')
    proc, url = start_server([DEMO, demo_ckpt], log)
    yield dict(url=url, proc=proc)
    stop_group(proc)
    log.close()


@pytest.fixture(scope='module')
def local(demo_ckpt):
    return Predictor(DEMO, demo_ckpt)


@pytest.fixture(scope='module')
def frames(cityscapes_like_root):
    files = sorted(glob.glob(osp.join(cityscapes_like_root, 'leftImg8bit*',
                                      'val', '*', '*.png')))
    return [(osp.basename(f), cv2.imread(f)) for f in files[:6]]


def post(url, img, ctype='image/png'):
    body = cv2.imencode('.png', img)[1].tobytes()
    return requests.post(url + '/predict', data=body,
                         headers={'Content-Type': ctype}, timeout=60)


def test_health_and_info(server):
    assert requests.get(server['url'] + '/health').json() == dict(
        status='ok')
    info = requests.get(server['url'] + '/info').json()
    assert info['weights'] == 'checkpoint'
    assert info['config'] == osp.basename(DEMO)
    assert info['classes'] == list(CityscapesDataset.METAINFO['classes'])
    assert info['batching']['max_batch_size'] == 4
    assert info['engine'].startswith('ray[serve]')


def test_predict_matches_detinferencer(server, local, frames):
    name, img = frames[0]
    resp = post(server['url'], img)
    assert resp.status_code == 200, resp.text
    got = resp.json()
    ref = local.predict([img])[0]
    assert (got['height'], got['width']) == img.shape[:2]
    assert got['labels'] == ref['labels']
    np.testing.assert_allclose(got['scores'], ref['scores'], atol=1e-4)
    np.testing.assert_allclose(got['bboxes'], ref['bboxes'], atol=1e-2)
    assert len(got['masks']) == len(got['labels'])
    for rle in got['masks'][:3]:
        assert mask_util.decode(
            dict(size=rle['size'], counts=rle['counts'].encode())
        ).shape == img.shape[:2]


def test_concurrent_requests_are_batched_and_equal(server, frames):
    imgs = [img for _, img in frames[:4]]
    serial = [post(server['url'], img).json() for img in imgs]
    with ThreadPoolExecutor(4) as pool:
        parallel = [r.json() for r in pool.map(
            lambda img: post(server['url'], img), imgs)]
    for a, b in zip(serial, parallel):
        assert a['labels'] == b['labels']
        np.testing.assert_allclose(a['bboxes'], b['bboxes'], atol=1e-2)


def test_bad_input_4xx_and_server_keeps_serving(server, frames):
    from serving_helpers import png_header
    url = server['url'] + '/predict'
    cases = [
        (b'', 'image/png', 400),
        (b'not an image', 'image/png', 400),
        (png_header(20000, 20000), 'image/png', 413),
        (b'{"a": 1}', 'application/json', 415),
    ]
    for body, ctype, status in cases:
        resp = requests.post(url, data=body, headers={'Content-Type': ctype},
                             timeout=30)
        assert resp.status_code == status, (ctype, resp.text)
        assert resp.json()['error']
    assert post(server['url'], frames[0][1]).status_code == 200
    assert requests.get(server['url'] + '/health').status_code == 200


def test_route_cli_over_a_folder(server, demo_ckpt, frames, tmp_path):
    folder = tmp_path / 'frames'
    folder.mkdir()
    for name, img in frames[:2]:
        cv2.imwrite(str(folder / name), img)
    out = tmp_path / 'out'
    subprocess.run(
        [sys.executable, osp.join(TOOLS, 'route.py'), DEMO,
         demo_ckpt, '--input', str(folder), '--out-dir', str(out),
         '--server-url', server['url'], '--mode', 'server'],
        cwd=ROOT, check=True, timeout=120,
        env=dict(os.environ, OMP_NUM_THREADS='1'))
    recs = [json.loads(line) for line in open(out / 'results.jsonl')]
    assert [r['frame'] for r in recs] == sorted(n for n, _ in frames[:2])
    assert [r['where'] for r in recs] == ['server', 'server']
    assert all('bboxes' in r['prediction'] for r in recs)
    # run.json names both models' classes (offload_eval.py maps labels
    # through them) and the thresholds the run used
    run = json.load(open(out / 'run.json'))
    assert run['router']['mode'] == 'server'
    assert run['local']['classes'] == run['server']['classes']
    assert len(run['server']['classes']) == 8


def test_router_end_to_end_on_a_real_format_stream(server, demo_ckpt,
                                                   tmp_path):
    """make_stream.py (a VOC fog folder + a COCO file of photos, the real
    data's formats) -> route.py local, server and auto against the live
    server -> offload_eval.py --conditions folder. Local and server run
    the same model and weights here, so every policy must score what
    always-local scores: whichever frames are offloaded, the predictions
    are the same."""
    from serving_helpers import tiny_coco

    from cbnet_tools.synthetic.voc_folder import tiny_fog_folder
    fog = str(tmp_path / 'fog')
    tiny_fog_folder(fog, num_images=10)
    ann, imgs = tiny_coco(str(tmp_path / 'coco'))
    stream = load_tool('projects/edge_serving/tools/make_stream.py').main(
        [str(tmp_path / 'stream'), '--voc', f'fog={fog}', '--coco',
         f'clear={ann}:{imgs}'])
    runs = {}
    for mode in ('local', 'server', 'auto'):
        runs[mode] = str(tmp_path / mode)
        subprocess.run(
            [sys.executable, osp.join(TOOLS, 'route.py'), DEMO, demo_ckpt,
             '--input', stream['frames'],
             '--out-dir', runs[mode], '--server-url', server['url'],
             '--mode', mode, '--timeout-s', '60'],
            cwd=ROOT, check=True, timeout=300,
            env=dict(os.environ, OMP_NUM_THREADS='1'))
    # the server answered each photo (JPEGs of the COCO file, the VOC
    # folder's images) as the local model did
    recs = {m: {json.loads(x)['frame']: json.loads(x) for x in
                open(osp.join(runs[m], 'results.jsonl'))}
            for m in ('local', 'server')}
    assert sorted(recs['local']) == sorted(recs['server'])
    assert any(f.endswith('.jpg') for f in recs['local'])
    assert {r['where'] for r in recs['server'].values()} == {'server'}
    boxes = 0
    for f, r in recs['local'].items():
        a, b = r['prediction'], recs['server'][f]['prediction']
        assert a['labels'] == b['labels'], f
        np.testing.assert_allclose(a['bboxes'], b['bboxes'], atol=1e-2)
        boxes += len(a['bboxes'])
    assert boxes > 0  # the check above compared something
    res = load_tool('projects/edge_serving/tools/offload_eval.py').main(
        [runs['local'], runs['server'], '--ann', stream['ann_file'],
         '--conditions', 'folder', '--boxes-only', '--auto', runs['auto'],
         '--out-dir', str(tmp_path / 'eval')])
    n = sum(stream['counts'].values())
    assert res['frames'] == n == 6 and res['conditions'] == ['clear', 'fog']
    rows = {r['policy']: r for r in res['rows']}
    live = rows['live auto run (route.py --mode auto)']
    assert live['fallbacks'] == 0
    base = rows['always local']['bbox_mAP']
    for r in res['rows']:
        assert r['bbox_mAP'] == pytest.approx(base, abs=1e-6), r['policy']
    assert {r['rule'] for r in res['rows']} >= {
        'local', 'haze', 'confidence', 'shipped', 'server', 'auto'}


def test_load_test_cli(server, tmp_path):
    """projects/edge_serving/tools/load_test.py (the docs' measurement) on
    a small image."""
    load_test = load_tool('projects/edge_serving/tools/load_test.py')
    out = tmp_path / 'load.json'
    load_test.main([server['url'], '--size', '64', '128', '--concurrency',
                    '1', '2', '--requests', '2', '--out', str(out)])
    levels = json.load(open(out))['levels']
    assert [lv['concurrency'] for lv in levels] == [1, 2]
    assert all(lv['errors'] == 0 and lv['p50_s'] > 0 for lv in levels)
    # a folder of real-format frames (a JPEG and a PNG, two sizes), each
    # sent as its file's bytes in turn
    frames = tmp_path / 'frames' / 'fog'
    frames.mkdir(parents=True)
    rng = np.random.default_rng(0)
    cv2.imwrite(str(frames / 'a.jpg'),
                rng.integers(0, 256, (48, 64, 3)).astype(np.uint8))
    cv2.imwrite(str(frames / 'b.png'),
                rng.integers(0, 256, (40, 72, 3)).astype(np.uint8))
    load_test.main([server['url'], '--images', str(tmp_path / 'frames'),
                    '--concurrency', '2', '--requests', '3', '--out',
                    str(out)])
    res = json.load(open(out))
    assert res['images'] == 2 and res['image_shapes'] == [[40, 72],
                                                          [48, 64]]
    assert res['levels'][0]['errors'] == 0


def test_load_test_bad_input(tmp_path):
    load_test = load_tool('projects/edge_serving/tools/load_test.py')
    with pytest.raises(FileNotFoundError, match='no images'):
        load_test.main(['http://127.0.0.1:9', '--images', str(tmp_path)])
    (tmp_path / 'broken.jpg').write_bytes(b'not a jpeg')
    with pytest.raises(ValueError, match='cannot decode'):
        load_test.main(['http://127.0.0.1:9', '--images', str(tmp_path)])
    with pytest.raises(FileNotFoundError, match='cannot read --image'):
        load_test.main(['http://127.0.0.1:9', '--image',
                        str(tmp_path / 'none.png')])
    with pytest.raises(SystemExit):  # one source of images at a time
        load_test.parse_args(['u', '--image', 'a.png', '--images', 'b'])


def wait_until_down(url, timeout_s=30):
    """Ray's HTTP proxy can outlive the killed driver by a moment."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            requests.get(url + '/health', timeout=1)
        except requests.RequestException:
            return
        time.sleep(0.2)
    pytest.fail(f'{url} still answers {timeout_s} s after the kill')


def test_clean_stop_exits_0_and_logs_no_failure(tmp_path):
    """Ctrl+C (SIGINT to the leader, as a terminal sends it): the app is
    deleted and Ray shut down, exit status 0, and nothing in the log that
    reads like a failure (serve.shutdown() made Ray log "Task
    ServeController.graceful_shutdown failed" on every clean stop)."""
    with open(tmp_path / 'server.log', 'w+') as log:
        proc, url = start_server([DEMO], log)
        try:
            # what the user sees before pressing Ctrl+C
            deadline = time.monotonic() + 60
            while f'on {url} (POST /predict' not in open(log.name).read():
                assert time.monotonic() < deadline, 'no "serving" line'
                time.sleep(0.2)
            proc.send_signal(signal.SIGINT)
            assert proc.wait(90) == 0
        finally:
            stop_group(proc)
        log.seek(0)
        text = log.read()
    assert "Deleting app ['detector']" in text
    for alarming in ('failed', 'Traceback', 'ERROR'):
        assert alarming not in text, text[-3000:]


def test_server_killed_mid_run_every_frame_answered(server, local, frames):
    """Must stay the module's last test: it kills the server."""
    router = EdgeRouter(local, RouterConfig(server_url=server['url'],
                                            mode='server', timeout_s=10))
    recs = []
    for i, (name, img) in enumerate(frames):
        if i == 2:
            os.killpg(server['proc'].pid, signal.SIGKILL)
            server['proc'].wait(30)
            wait_until_down(server['url'])
        recs.append(router(img, name))
    assert [r['frame'] for r in recs] == [n for n, _ in frames]
    assert [r['where'] for r in recs[:2]] == ['server'] * 2
    assert all(r['where'] == 'local-fallback' for r in recs[2:])
    assert all('server failed' in r['reason'] for r in recs[2:])
    assert all('scores' in r['prediction'] for r in recs)
