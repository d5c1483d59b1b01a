"""Edge router over a folder of images or a video.

Usage::

    python projects/edge_serving/tools/route.py LOCAL_CONFIG \
        [LOCAL_CHECKPOINT] \
        --input FOLDER_OR_VIDEO --out-dir OUT \
        [--router-cfg projects/edge_serving/tools/edge_router.py] \
        [--server-url http://127.0.0.1:8000] [--mode auto|local|server] \
        [--timeout-s 5]

``LOCAL_CONFIG`` may be an ``.onnx`` file of ``export_onnx.py`` (no
checkpoint then): the local model runs on ONNX Runtime, as an edge device
runs it.

Writes ``OUT/results.jsonl`` (one line per frame: frame, where, reason,
transmission, local_top_score, seconds, prediction), ``OUT/run.json`` (the
router's thresholds, the local model's and the server's ``/info``: their
classes name the labels) and prints a summary of where frames were
processed (local / server / local-fallback). ``offload_eval.py`` scores
such runs against ground truth.
"""
import argparse
import json
import os
import os.path as osp
from collections import Counter


def parse_args(argv=None):
    here = osp.dirname(osp.abspath(__file__))
    p = argparse.ArgumentParser(description='cbnet_mmdet edge router')
    p.add_argument('config', help='local (light) detector config, or an '
                   '.onnx file of export_onnx.py')
    p.add_argument('checkpoint', nargs='?', help='local checkpoint')
    p.add_argument('--input', required=True,
                   help='folder of images (searched recursively) or video')
    p.add_argument('--out-dir', required=True)
    p.add_argument('--router-cfg', default=osp.join(here, 'edge_router.py'))
    p.add_argument('--server-url')
    p.add_argument('--mode', choices=['auto', 'local', 'server'])
    p.add_argument('--timeout-s', type=float)
    p.add_argument('--device', default='cpu')
    args = p.parse_args(argv)
    if args.config.endswith('.onnx') and args.checkpoint:
        p.error(f'{args.config} carries its weights: give no checkpoint')
    return args


def iter_frames(path):
    """(name, BGR frame) of a folder's images (sorted) or a video."""
    import mmcv

    from cbnet_serving.stream import list_images
    if osp.isdir(path):
        for f in list_images(path):
            yield osp.relpath(f, path), mmcv.imread(f, channel_order='bgr')
    elif osp.isfile(path):
        video = mmcv.VideoReader(path)
        for i, frame in enumerate(video):
            yield f'frame_{i:06d}', frame
    else:
        raise FileNotFoundError(f'--input {path} is neither a folder nor a '
                                'file')


def main(argv=None):
    args = parse_args(argv)
    os.environ.setdefault('OMP_NUM_THREADS', '1')
    from mmengine.config import Config

    from cbnet_serving.predictor import Predictor
    from cbnet_serving.router import EdgeRouter, RouterConfig
    values = dict(Config.fromfile(args.router_cfg).get('router', {}))
    for key in ('server_url', 'mode', 'timeout_s'):
        if getattr(args, key) is not None:
            values[key] = getattr(args, key)
    if args.config.endswith('.onnx'):
        from cbnet_serving.onnx_predictor import OnnxPredictor
        local = OnnxPredictor(args.config)
    else:
        local = Predictor(args.config, args.checkpoint, args.device)
    router = EdgeRouter(local, RouterConfig(**values))
    os.makedirs(args.out_dir, exist_ok=True)
    server = None if router.cfg.mode == 'local' else router.server_info()
    with open(osp.join(args.out_dir, 'run.json'), 'w') as f:
        json.dump(dict(router=router.config(), local=local.info(),
                       server=server), f, indent=1)
    counts = Counter()
    out = osp.join(args.out_dir, 'results.jsonl')
    with open(out, 'w') as f:
        for name, frame in iter_frames(args.input):
            rec = router(frame, name)
            counts[rec['where']] += 1
            f.write(json.dumps(rec) + '\n')
            f.flush()
            print(f"{name}: {rec['where']} ({rec['reason']})", flush=True)
    print(json.dumps(dict(frames=sum(counts.values()), **counts,
                          results=out, router=router.config())))


if __name__ == '__main__':
    main()
