"""Frames per second of edge models as the router runs them, like for like.

Every model is a predictor of the serving code (:class:`.predictor.
Predictor` for a config + checkpoint, PyTorch eager through
``DetInferencer``; :class:`.onnx_predictor.OnnxPredictor` for an exported
file on ONNX Runtime) and is timed on its whole ``predict([frame])`` call,
what the router pays per frame: resizing and padding, the network, decoding
and NMS, the results as lists. The same frame for all, warm-up calls not
timed, the models in alternation (``m1, m2, ..., m1, m2, ...``) so that a
load change on a shared machine hits all alike. Per model: wall time per
frame (median, 95th percentile), frames/s (1 / median), the process's CPU
time per frame (on a loaded machine the wall time includes time the
scheduler gave other processes; with one thread the CPU time estimates an
idle core), and the input the network got.
"""
import os
import platform
import time
from typing import Dict

import numpy as np


def network_input(predictor, frame: np.ndarray):
    """(H, W) of the tensor the predictor's network gets for ``frame``."""
    if hasattr(predictor, 'meta'):  # an OnnxPredictor
        from .onnx_predictor import letterbox
        return list(letterbox(frame, predictor.meta)[0].shape[-2:])
    from mmengine.dataset import pseudo_collate
    inferencer = predictor.inferencer
    data = inferencer.model.data_preprocessor(
        pseudo_collate([inferencer.pipeline(frame)]), False)
    return list(data['inputs'].shape[-2:])


def time_predictors(predictors: Dict[str, object], frame: np.ndarray,
                    repeats: int = 20, warmup: int = 2) -> Dict[str, Dict]:
    """Time ``predict([frame])`` of each predictor in alternation.

    Returns per name: ``wall`` and ``cpu`` (seconds of every timed call),
    ``p50``/``p95`` (wall), ``cpu_p50``/``cpu_p95``, ``fps`` (1 / p50),
    ``fps_cpu`` (1 / cpu_p50), ``detections`` (of the last call),
    ``input`` (H, W of the network's input)."""
    if repeats < 1 or warmup < 0:
        raise ValueError(f'repeats must be >= 1 and warmup >= 0, got '
                         f'{repeats}, {warmup}')
    for _ in range(warmup):
        for p in predictors.values():
            p.predict([frame])
    wall = {n: [] for n in predictors}
    cpu = {n: [] for n in predictors}
    last = {}
    for _ in range(repeats):
        for name, p in predictors.items():
            c0, t0 = time.process_time(), time.perf_counter()
            last[name] = p.predict([frame])[0]
            wall[name].append(time.perf_counter() - t0)
            cpu[name].append(time.process_time() - c0)
    out = {}
    for name, p in predictors.items():
        w, c = np.asarray(wall[name]), np.asarray(cpu[name])
        out[name] = dict(
            wall=w.tolist(), cpu=c.tolist(), p50=float(np.median(w)),
            p95=float(np.percentile(w, 95)), cpu_p50=float(np.median(c)),
            cpu_p95=float(np.percentile(c, 95)),
            fps=float(1 / np.median(w)), fps_cpu=float(1 / np.median(c)),
            detections=len(last[name]['scores']),
            input=network_input(p, frame))
    return out


def machine() -> Dict:
    """Where it ran: platform, CPU count, library versions."""
    info = dict(platform=platform.platform(), cpus=os.cpu_count(),
                omp_num_threads=os.environ.get('OMP_NUM_THREADS'))
    for mod in ('torch', 'onnxruntime', 'mmdet', 'mmcv'):
        try:
            info[mod] = __import__(mod).__version__
        except ImportError:
            info[mod] = None
    return info


def to_markdown(results: Dict[str, Dict], runtimes: Dict[str, str],
                reference: str) -> str:
    """One line per model; the last column is its latency over the
    reference model's."""
    from cbnet_tools.markdown import markdown_table
    ref = results[reference]['p50']
    head = ['model', 'runtime', 'network input (HxW)',
            'latency p50 / p95 (s)', 'frames/s', 'CPU time p50 (s)',
            'frames/s by CPU time', 'detections', f'latency / {reference}']
    rows = []
    for name, r in results.items():
        rows.append([
            name, runtimes[name], 'x'.join(map(str, r['input'])),
            f"{r['p50']:.4f} / {r['p95']:.4f}", f"{r['fps']:.1f}",
            f"{r['cpu_p50']:.4f}", f"{r['fps_cpu']:.1f}",
            str(r['detections']), f"{r['p50'] / ref:.2f}"])
    return '\n'.join(markdown_table(head, rows)) + '\n'
