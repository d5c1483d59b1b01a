"""The edge router: a light local detector, offload to the server on haze
or low confidence, local fallback when the server is slow or down.

Per frame:

1. the local model detects, the haze estimate ``transmission`` (mean DCP
   transmission, :class:`.haze.HazeEstimator`) is computed;
2. the frame is offloaded when ``transmission < transmission_thr``
   (reason ``haze``) or when the local top score ``< min_confidence``
   (reason ``low-confidence``); otherwise it stays ``local``;
3. an offloaded frame is POSTed to the server with ``timeout_s``; on a
   timeout, a refused connection or a non-200 answer the local result is
   kept as ``local-fallback`` with the error as the reason.

Every frame gets one log record and one result; nothing is dropped.
"""
import time
from dataclasses import asdict, dataclass
from typing import Dict, Optional

import cv2
import numpy as np
import requests

from .haze import HazeEstimator


@dataclass
class RouterConfig:
    """Thresholds of the router (the ``router`` dict of a router config
    file, e.g. ``projects/edge_serving/tools/edge_router.py``).

    Attributes:
        server_url (str): base URL of the model server.
        transmission_thr (float): offload when the mean transmission is
            below this (hazy frame). 0 disables.
        min_confidence (float): offload when the local top score is below
            this. 0 disables.
        timeout_s (float): seconds to wait for the server.
        haze_max_side (int): haze estimate's working resolution, pixels.
        mode (str): ``auto`` (the rules above), ``local`` (never offload)
            or ``server`` (always offload).
    """
    server_url: str = 'http://127.0.0.1:8000'
    transmission_thr: float = 0.6
    min_confidence: float = 0.3
    timeout_s: float = 5.0
    haze_max_side: int = 256
    mode: str = 'auto'

    def __post_init__(self) -> None:
        if self.mode not in ('auto', 'local', 'server'):
            raise ValueError(f"router mode must be 'auto', 'local' or "
                             f"'server', got {self.mode!r}")
        if self.timeout_s <= 0:
            raise ValueError(f'router timeout_s must be > 0, got '
                             f'{self.timeout_s}')


def decide(cfg: RouterConfig, transmission: float,
           top_score: float) -> Optional[str]:
    """The reason to offload a frame, or None to keep it local."""
    if cfg.mode == 'local':
        return None
    if cfg.mode == 'server':
        return 'always-server'
    if transmission < cfg.transmission_thr:
        return f'haze (transmission {transmission:.3f} < ' \
               f'{cfg.transmission_thr})'
    if top_score < cfg.min_confidence:
        return f'low-confidence (top score {top_score:.3f} < ' \
               f'{cfg.min_confidence})'
    return None


class EdgeRouter:
    """Route frames between a local predictor and the server.

    Args:
        local: an object with ``predict(list of BGR images) -> list of
            pred dicts`` (:class:`.predictor.Predictor`).
        cfg (RouterConfig): thresholds.
    """

    def __init__(self, local, cfg: RouterConfig) -> None:
        self.local = local
        self.cfg = cfg
        self.haze = HazeEstimator(max_side=cfg.haze_max_side)
        self.session = requests.Session()

    def ask_server(self, img: np.ndarray) -> Dict:
        """POST the frame (PNG) to the server; raises on any failure."""
        ok, buf = cv2.imencode('.png', img)
        if not ok:
            raise ValueError('could not encode the frame as PNG')
        resp = self.session.post(
            self.cfg.server_url.rstrip('/') + '/predict',
            data=buf.tobytes(), headers={'Content-Type': 'image/png'},
            timeout=self.cfg.timeout_s)
        if resp.status_code != 200:
            raise RuntimeError(
                f'server answered {resp.status_code}: {resp.text[:200]}')
        pred = resp.json()
        pred.pop('height', None)
        pred.pop('width', None)
        return pred

    def server_info(self) -> Optional[Dict]:
        """The server's ``GET /info`` (its model and classes), or None
        when it does not answer within ``timeout_s``."""
        try:
            resp = self.session.get(
                self.cfg.server_url.rstrip('/') + '/info',
                timeout=self.cfg.timeout_s)
            return resp.json() if resp.status_code == 200 else None
        except (requests.RequestException, ValueError):
            return None

    def __call__(self, img: np.ndarray, frame: str = '') -> Dict:
        """Process one BGR frame: ``{'frame', 'where', 'reason',
        'transmission', 'local_top_score', 'seconds', 'prediction'}``."""
        start = time.perf_counter()
        local = self.local.predict([img])[0]
        transmission = self.haze(img)
        top = max(local.get('scores') or [0.0])
        reason = decide(self.cfg, transmission, top)
        where, pred = 'local', local
        if reason is None:
            reason = 'always-local' if self.cfg.mode == 'local' else \
                'clear and confident'
        else:
            try:
                pred = self.ask_server(img)
                where = 'server'
            except (requests.RequestException, RuntimeError,
                    ValueError) as err:
                where = 'local-fallback'
                reason = f'{reason}; server failed: ' \
                         f'{type(err).__name__}: {str(err)[:200]}'
        return dict(frame=frame, where=where, reason=reason,
                    transmission=transmission, local_top_score=top,
                    seconds=time.perf_counter() - start, prediction=pred)

    def config(self) -> Dict:
        return asdict(self.cfg)
