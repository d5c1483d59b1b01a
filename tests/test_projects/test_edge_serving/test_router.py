"""The edge router's decisions and failure paths (no model server)."""
import http.server
import socket
import threading
import time

import numpy as np
import pytest

from cbnet_serving.haze import HazeEstimator
from cbnet_serving.router import EdgeRouter, RouterConfig, decide


class FakeLocal:
    """A local predictor answering a fixed top score."""

    def __init__(self, score):
        self.score = score

    def predict(self, images):
        return [dict(labels=[0], scores=[self.score],
                     bboxes=[[0., 0., 1., 1.]]) for _ in images]


def scene(h=64, w=96, seed=0):
    """A textured clear scene (BGR uint8) with dark pixels in every
    patch, as the dark channel prior assumes."""
    rng = np.random.default_rng(seed)
    return rng.integers(0, 256, (h, w, 3)).astype(np.uint8)


def fog(img, t, light=230):
    """The scattering model I = J t + A (1 - t), constant t."""
    return np.clip(img * t + light * (1 - t), 0, 255).astype(np.uint8)


def test_haze_estimate_matches_the_scattering_model():
    haze = HazeEstimator(patch_size=7, guided_radius=4)
    clear = scene()
    assert haze(clear) > 0.9
    for t in (0.7, 0.4, 0.2):
        # omega = 0.95 keeps 5% of the haze: t_est = 1 - 0.95 (1 - t)
        assert haze(fog(clear, t)) == pytest.approx(1 - 0.95 * (1 - t),
                                                    abs=0.06)
    with pytest.raises(ValueError, match='HxWx3'):
        haze(np.zeros((4, 4), np.uint8))


@pytest.mark.parametrize('t,score,mode,reason', [
    (0.9, 0.9, 'auto', None),
    (0.5, 0.9, 'auto', 'haze'),
    (0.9, 0.1, 'auto', 'low-confidence'),
    (0.5, 0.1, 'auto', 'haze'),
    (0.1, 0.0, 'local', None),
    (0.9, 0.9, 'server', 'always-server'),
])
def test_decide(t, score, mode, reason):
    cfg = RouterConfig(transmission_thr=0.6, min_confidence=0.3, mode=mode)
    got = decide(cfg, t, score)
    if reason is None:
        assert got is None
    else:
        assert got.startswith(reason)


def test_bad_router_config():
    with pytest.raises(ValueError, match='mode'):
        RouterConfig(mode='cloud')
    with pytest.raises(ValueError, match='timeout_s'):
        RouterConfig(timeout_s=0)


def unused_port():
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def test_server_down_falls_back_to_local():
    cfg = RouterConfig(server_url=f'http://127.0.0.1:{unused_port()}',
                       mode='server', timeout_s=2)
    rec = EdgeRouter(FakeLocal(0.8), cfg)(scene(), 'a.png')
    assert rec['where'] == 'local-fallback'
    assert 'ConnectionError' in rec['reason']
    assert rec['prediction']['scores'] == [0.8]


def test_clear_confident_frame_stays_local():
    cfg = RouterConfig(server_url=f'http://127.0.0.1:{unused_port()}')
    rec = EdgeRouter(FakeLocal(0.8), cfg)(scene(), 'a.png')
    assert rec['where'] == 'local'
    assert rec['reason'] == 'clear and confident'


def test_forced_local_frame_says_so():
    """--mode local keeps a hazy, unsure frame local: the reason names
    the mode, not the haze rule."""
    cfg = RouterConfig(server_url=f'http://127.0.0.1:{unused_port()}',
                       mode='local')
    rec = EdgeRouter(FakeLocal(0.1), cfg)(fog(scene(), 0.2), 'a.png')
    assert rec['where'] == 'local'
    assert rec['reason'] == 'always-local'


class Slow(http.server.BaseHTTPRequestHandler):
    """Answers after 3 s, or 503 at once for /busy."""

    def do_POST(self):
        self.rfile.read(int(self.headers['Content-Length']))
        if self.path.startswith('/busy'):
            self.send_response(503)
            self.end_headers()
            self.wfile.write(b'busy')
            return
        time.sleep(3)
        self.send_response(200)
        self.end_headers()

    def log_message(self, *args):
        pass


@pytest.fixture
def slow_server():
    server = http.server.ThreadingHTTPServer(('127.0.0.1', 0), Slow)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f'http://127.0.0.1:{server.server_address[1]}'
    server.shutdown()
    server.server_close()


def test_slow_server_times_out_to_local(slow_server):
    cfg = RouterConfig(server_url=slow_server, timeout_s=0.5)
    start = time.perf_counter()
    rec = EdgeRouter(FakeLocal(0.8), cfg)(fog(scene(), 0.3), 'f.png')
    assert time.perf_counter() - start < 2.5
    assert rec['where'] == 'local-fallback'
    assert rec['reason'].startswith('haze')
    assert 'Timeout' in rec['reason']


def test_server_error_status_falls_back(slow_server):
    cfg = RouterConfig(server_url=slow_server + '/busy', mode='server')
    rec = EdgeRouter(FakeLocal(0.8), cfg)(scene(), 'b.png')
    assert rec['where'] == 'local-fallback'
    assert '503' in rec['reason']
