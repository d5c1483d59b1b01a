"""The model server: a Ray Serve deployment with a FastAPI HTTP API.

Endpoints (all JSON):

* ``POST /predict``: body = the encoded image (PNG, JPEG, ...),
  Content-Type ``image/*`` or ``application/octet-stream``; answers
  ``{"height", "width", "labels", "scores", "bboxes"[, "masks"]}`` in
  MMDet's ``DetInferencer`` field names (masks as pycocotools RLE). Bad
  input answers 4xx with ``{"error": ...}`` (see :func:`.codec.decode_image`).
* ``GET /health``: ``{"status": "ok"}``.
* ``GET /info``: config, checkpoint, classes, batching and replicas.

Requests are batched by ``ray.serve.batch`` (up to ``max_batch_size``
images waiting at most ``batch_wait_timeout_s``) and run through
:class:`.predictor.Predictor` as one ``DetInferencer`` batch.
"""
import importlib.util
import os
import signal
import site
import time
from typing import Dict, List, Optional

import numpy as np
import ray
from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse
from ray import serve

from .codec import (DEFAULT_MAX_BYTES, DEFAULT_MAX_PIXELS, BadImage,
                    decode_image)

api = FastAPI(title='cbnet_mmdet detector')


@serve.deployment(name='detector')
@serve.ingress(api)
class DetectorDeployment:
    """One replica: a :class:`Predictor` and the HTTP routes."""

    def __init__(self, config: str, checkpoint: Optional[str], device: str,
                 max_batch_size: int, batch_wait_timeout_s: float,
                 max_pixels: int, max_bytes: int) -> None:
        import torch

        from .predictor import Predictor
        torch.set_num_threads(int(os.environ.get('OMP_NUM_THREADS', '1')))
        self.predictor = Predictor(config, checkpoint, device)
        self.max_pixels = max_pixels
        self.max_bytes = max_bytes
        self.batching = dict(max_batch_size=max_batch_size,
                             batch_wait_timeout_s=batch_wait_timeout_s)
        self._run_batch.set_max_batch_size(max_batch_size)
        self._run_batch.set_batch_wait_timeout_s(batch_wait_timeout_s)

    @api.get('/health')
    def health(self) -> Dict:
        return dict(status='ok')

    @api.get('/info')
    def info(self) -> Dict:
        return dict(self.predictor.info(), batching=self.batching,
                    max_pixels=self.max_pixels, max_bytes=self.max_bytes,
                    engine=f'ray[serve] {ray.__version__}')

    @api.post('/predict')
    async def predict(self, request: Request):
        length = request.headers.get('content-length')
        if length is not None and length.isdigit() and \
                int(length) > self.max_bytes:
            return JSONResponse(
                status_code=413,
                content=dict(error=f'body of {length} bytes is over the '
                             f'limit of {self.max_bytes} bytes'))
        body = await request.body()
        try:
            img = decode_image(body, request.headers.get('content-type'),
                               self.max_pixels, self.max_bytes)
        except BadImage as err:
            return JSONResponse(status_code=err.status,
                                content=dict(error=str(err)))
        pred = await self._run_batch(img)
        return dict(height=int(img.shape[0]), width=int(img.shape[1]),
                    **pred)

    @serve.batch(max_batch_size=4, batch_wait_timeout_s=0.01)
    async def _run_batch(self, images: List[np.ndarray]) -> List[Dict]:
        return self.predictor.predict(images)


def build_app(config: str,
              checkpoint: Optional[str] = None,
              device: str = 'cpu',
              num_replicas: int = 1,
              max_batch_size: int = 4,
              batch_wait_timeout_s: float = 0.01,
              max_pixels: int = DEFAULT_MAX_PIXELS,
              max_bytes: int = DEFAULT_MAX_BYTES,
              replica_cpus: float = 0):
    """The Ray Serve application of one detector (for ``serve.run`` or a
    Ray Serve config file on a cluster)."""
    return DetectorDeployment.options(
        num_replicas=num_replicas,
        ray_actor_options=dict(num_cpus=replica_cpus)).bind(
            os.path.abspath(config),
            os.path.abspath(checkpoint) if checkpoint else None, device,
            max_batch_size, batch_wait_timeout_s, max_pixels, max_bytes)


#: The packages a replica imports besides this one: the plugin (the
#: predictor) and the peer baseline's (configs that load it).
WORKER_PACKAGES = ('cbnet_mmdet', 'cbnet_dehaze')


def worker_pythonpath() -> str:
    """PYTHONPATH for Ray's workers: the caller's, plus the folders this
    package and :data:`WORKER_PACKAGES` were found in when they are source
    trees (the repository root, ``projects/edge_serving``,
    ``projects/peer_dehaze``; so that workers import the same code). An
    installed package's folder is site-packages, which is never put there:
    on PYTHONPATH it would come ahead of the standard library, and the
    `typing` 3.7 backport that cityscapesScripts installs into
    site-packages would then shadow Python's own `typing` and break
    `import ray` in every worker."""
    origins = [__file__]
    for name in WORKER_PACKAGES:
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.origin:
            origins.append(spec.origin)
    site_dirs = {os.path.realpath(d) for d in
                 site.getsitepackages() + [site.getusersitepackages()]}
    folders = []
    for origin in origins:
        # <folder>/<package>/<module>.py -> <folder>
        folder = os.path.dirname(os.path.dirname(os.path.abspath(origin)))
        if os.path.realpath(folder) not in site_dirs and \
                folder not in folders:
            folders.append(folder)
    return os.pathsep.join(
        folders + [p for p in [os.environ.get('PYTHONPATH')] if p])


def run_local(config: str,
              checkpoint: Optional[str] = None,
              host: str = '127.0.0.1',
              port: int = 8000,
              num_cpus: Optional[int] = None,
              **kwargs) -> None:
    """Start a one-machine Ray, serve the detector, block until SIGINT or
    SIGTERM, then delete the app and shut that Ray down."""
    env = {'OMP_NUM_THREADS': os.environ.get('OMP_NUM_THREADS', '1'),
           'PYTHONPATH': worker_pythonpath()}
    ray.init(num_cpus=num_cpus, include_dashboard=False,
             runtime_env=dict(env_vars=env), logging_level='WARNING')
    serve.start(http_options=dict(host=host, port=port))
    serve.run(build_app(config, checkpoint, **kwargs), name='detector',
              route_prefix='/')
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.append(1))
    print(f'serving {config} on http://{host}:{port} '
          '(POST /predict, GET /health, GET /info)', flush=True)
    try:
        while not stop:
            time.sleep(0.2)
    finally:
        # drain the app (requests in flight finish), then end the Ray this
        # function started, Serve's actors with it. serve.shutdown() would
        # first ask the controller to stop itself; Ray then reports that
        # call as failed ("Task ServeController.graceful_shutdown failed
        # ... killed by `ray.kill`") on every clean stop.
        serve.delete('detector')
        ray.shutdown()
