"""Frames/s of edge models on one frame as the router runs them, like for
like (projects/edge_serving/README.md, "The exported edge model").

Usage::

    OMP_NUM_THREADS=1 python projects/edge_serving/tools/edge_speed.py \
        --model onnx_640 EDGE_640.onnx \
        --model eager_640 CONFIG CHECKPOINT \
        --model fcos-lite_320 FCOS_CONFIG [FCOS_CHECKPOINT] \
        [--image PHOTO] [--size 360 640] [--repeats 20] [--warmup 2] \
        [--reference onnx_640] --out-dir OUT

``--model NAME FILE [CHECKPOINT]`` (repeatable): an ``.onnx`` file of
``export_onnx.py`` runs on ONNX Runtime, a config (and checkpoint; random
weights without one) on PyTorch through ``DetInferencer``. The frame is
``--image`` resized to ``--size`` (H W, default 360 640: a 640x360 camera
frame), random pixels without it. One thread for both runtimes
(``--threads``). Writes ``OUT/edge_speed.json`` (every call's times, the
machine, the load average before and after) and ``OUT/edge_speed.md``.
"""
import argparse
import json
import os
import os.path as osp
import sys
import time
from datetime import datetime, timezone


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--model', nargs='+', action='append', required=True,
                   metavar='NAME FILE [CHECKPOINT]',
                   help='a model to time: NAME and an .onnx file, or NAME, '
                   'a config and optionally its checkpoint (repeatable)')
    p.add_argument('--image', help='a photo as the frame (resized to '
                   '--size); default random pixels')
    p.add_argument('--size', type=int, nargs=2, default=[360, 640],
                   metavar=('H', 'W'))
    p.add_argument('--repeats', type=int, default=20)
    p.add_argument('--warmup', type=int, default=2)
    p.add_argument('--threads', type=int, default=1)
    p.add_argument('--reference', help='the ratio column\'s model '
                   '(default: the first)')
    p.add_argument('--out-dir', required=True)
    args = p.parse_args(argv)
    models = {}
    for item in args.model:
        if len(item) not in (2, 3):
            p.error(f'--model {" ".join(item)}: give NAME FILE '
                    '[CHECKPOINT]')
        name, path, ckpt = item[0], item[1], (item[2:] or [None])[0]
        if name in models:
            p.error(f'--model {name} given twice')
        if path.endswith('.onnx') and ckpt:
            p.error(f'--model {name}: an .onnx file carries its weights; '
                    'no checkpoint')
        models[name] = (path, ckpt)
    args.models = models
    args.reference = args.reference or next(iter(models))
    if args.reference not in models:
        p.error(f'--reference {args.reference}: not one of {list(models)}')
    if min(args.size) < 1 or args.repeats < 1 or args.warmup < 0 or \
            args.threads < 1:
        p.error('--size, --repeats and --threads must be positive, '
                '--warmup >= 0')
    args.error = p.error
    return args


def check_files(args) -> None:
    """Every model file, checkpoint and --image exists (a usage error
    naming the first that does not, before anything is loaded)."""
    for name, (path, ckpt) in args.models.items():
        for f in (path, ckpt):
            if f is not None and not osp.isfile(f):
                args.error(f'--model {name}: no such file {f}')
    if args.image and not osp.isfile(args.image):
        args.error(f'--image {args.image}: no such file')


def main(argv=None):
    args = parse_args(argv)
    check_files(args)
    os.environ['OMP_NUM_THREADS'] = str(args.threads)
    import mmcv
    import numpy as np
    import torch

    from cbnet_serving.edge_speed import machine, time_predictors, \
        to_markdown
    torch.set_num_threads(args.threads)
    h, w = args.size
    if args.image:
        frame = mmcv.imread(args.image)
        if frame is None:
            raise SystemExit(f'--image {args.image}: not a readable image')
        frame = mmcv.imresize(frame, (w, h))
    else:
        frame = np.random.default_rng(0).integers(
            0, 256, (h, w, 3), dtype=np.uint8)
    predictors, runtimes = {}, {}
    for name, (path, ckpt) in args.models.items():
        if path.endswith('.onnx'):
            from cbnet_serving.onnx_predictor import OnnxPredictor
            predictors[name] = OnnxPredictor(path, threads=args.threads)
            runtimes[name] = 'ONNX Runtime'
        else:
            from cbnet_serving.predictor import Predictor
            predictors[name] = Predictor(path, ckpt)
            runtimes[name] = 'PyTorch eager (DetInferencer)'
    load_start, start = os.getloadavg(), time.time()
    results = time_predictors(predictors, frame, args.repeats, args.warmup)
    meta = dict(
        date=datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC'),
        command='python projects/edge_serving/tools/edge_speed.py ' +
        ' '.join(sys.argv[1:] if argv is None else argv),
        frame=dict(size=args.size, image=args.image),
        repeats=args.repeats, warmup=args.warmup, threads=args.threads,
        models={n: dict(file=p, checkpoint=c, runtime=runtimes[n])
                for n, (p, c) in args.models.items()},
        machine=machine(), load_start=list(load_start),
        load_end=list(os.getloadavg()), wall_s=time.time() - start)
    md = to_markdown(results, runtimes, args.reference)
    os.makedirs(args.out_dir, exist_ok=True)
    with open(osp.join(args.out_dir, 'edge_speed.json'), 'w') as f:
        json.dump(dict(meta=meta, results=results), f, indent=1)
    with open(osp.join(args.out_dir, 'edge_speed.md'), 'w') as f:
        f.write(md)
    print(md)
    print(f"load average {meta['load_start']} -> {meta['load_end']}; "
          f"written {args.out_dir}/edge_speed.{{json,md}}")
    return results


if __name__ == '__main__':
    main()
