"""Cost of CBNet against the MMDetection baselines, in one run, on the same
synthetic inputs.

For every model (configs below, random weights, nothing downloaded):
parameters, GFLOPs (PyTorch's ``FlopCounterMode``: whole inference and
backbone+neck; mmcv's compiled ops count zero, see
``cbnet_lab.benchmark.count_flops``), inference latency at batch 1
(median, IQR, min, max over ``--repeats`` after ``--warmup``; the RoI
heads of two-stage models on one fixed, realistic proposal set,
``--proposals``), throughput at every ``--batch-sizes``, training step
time (loss, backward and the config's own optimiser step,
``--train-batch-size`` images), and peak memory of inference and of
a training step (CUDA: ``max_memory_allocated``; CPU: resident-set
high-water mark above the level at the start of the call, i.e. activations
and workspace on top of the weights; measured on one extra call, never on a
timed one). Models are measured in alternation
(``m1, m2, ..., m1, m2, ...``) so load changes on a shared machine hit all
alike. Then the scaling study for ``--scale-models``: inference latency and
memory against ``--scale-sizes``, and training step time and memory
against ``--scale-items`` ground-truth instances per image (RoI head and
loss cost).

``--suite edge`` measures the edge model next to the server
models of the real-fog deployment as the edge device runs them: one torch
thread, ``--size`` read as a camera frame (640x360) that each model gets
resized as its config's test pipeline resizes it (``--config-resize``;
the ``input`` column), optionally a real photo as that frame
(``--image``) and trained weights (``--checkpoint NAME FILE``), latency
median and 95th percentile after the warm-up, frames/s (``img/s b1``),
peak resident memory of a call and the weights; ratios to the edge model
(``--reference``).

Writes ``benchmark.json``, ``benchmark.md`` (tables, ratios to Cascade Mask
R-CNN Swin-S or ``--reference``) and ``scaling.png`` into ``--out-dir``;
prints the markdown.
Both record the command, the date, the machine (platform, CPU count or GPU
name), the torch thread count, the load average at the start and at the end
and the torch/mmcv/mmdet versions.

On a shared CPU pass ``--threads 1`` and set ``OMP_NUM_THREADS=1``: with
more threads than free cores, OpenMP threads spin waiting for each other
and ops get several times slower (and much noisier).

Usage::

    # CPU default: 128x256 (reduced size; see docs/benchmarks.md)
    python tools/analysis_tools/benchmark.py
    # shared CPU: one thread
    OMP_NUM_THREADS=1 python tools/analysis_tools/benchmark.py --threads 1
    # 512x1024, the 'cells' neck beside the default (the headline run,
    # with every model it compares, is in docs/benchmarks.md)
    OMP_NUM_THREADS=1 python tools/analysis_tools/benchmark.py --threads 1 \
        --models cbnet_mit-b5 b5_cells=cbnet_mit-b5 cascade-mask-rcnn_swin-s \
        --model-cfg b5_cells model.neck.fine_path=cells \
        --size 512 1024 --batch-sizes 1 --repeats 3 --no-train
    # GPU, fp32 then AMP, full sizes
    python tools/analysis_tools/benchmark.py --device cuda --size 1024 2048 \\
        --repeats 20 --warmup 5 \\
        --scale-sizes 256x512 512x1024 1024x2048
    python tools/analysis_tools/benchmark.py --device cuda --amp ...
    # the edge model against the servers, 640x360 frames, one thread
    # (projects/edge_serving/README.md "The earlier edge model: FCOS-lite")
    OMP_NUM_THREADS=1 python tools/analysis_tools/benchmark.py --suite edge \\
        --image data/dawn_fog/JPEGImages/foggy-001.jpg \\
        --out-dir docs/serving/edge_benchmark
"""
import argparse
import json
import os
import os.path as osp
import sys
import time
from datetime import datetime, timezone

from cbnet_lab import model_benchmark
from cbnet_lab.model_benchmark import (REFERENCE, machine, markdown,
                                       peak_memory_method, plot)
from cbnet_lab.report import load_average

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))

#: name -> config, relative to the repository root.
MODELS = {
    'cbnet_mit-b0': 'configs/cbnet/cbnet_mit-b0_nasfpn-crpn_8xb1-12e_'
    'cityscapes.py',
    'cbnet_mit-b2': 'configs/cbnet/cbnet_mit-b2_nasfpn-crpn_8xb1-12e_'
    'cityscapes.py',
    'cbnet_mit-b5': 'configs/cbnet/cbnet_mit-b5_nasfpn-crpn_8xb1-12e_'
    'cityscapes.py',
    'cascade-mask-rcnn_swin-s': 'configs/baselines/cascade-mask-rcnn_'
    'swin-s-p4-w7_fpn_1x_cityscapes.py',
    'mask-rcnn_pvt-v2-b2': 'configs/baselines/mask-rcnn_pvt-v2-b2_fpn_1x_'
    'cityscapes.py',
    'faster-rcnn_x101-64x4d': 'configs/baselines/faster-rcnn_x101-64x4d_'
    'fpn_1x_cityscapes.py',
    'yolox_s': 'configs/baselines/yolox_s_8xb8-300e_cityscapes.py',
    # the edge model and the server models of the real-fog
    # deployment, all on the pretrained MobileNetV2 (configs/pretrained/)
    'edge_fcos-lite_320': 'configs/pretrained/fcos-lite_mobilenet-v2_fpn_'
    '1xb2-ft_dawn-fog-320.py',
    'fcos-lite_640': 'configs/pretrained/fcos-lite_mobilenet-v2_fpn_1xb2-'
    'ft_dawn-fog.py',
    'server_cascade-rcnn': 'configs/pretrained/cascade-rcnn_mobilenet-v2_'
    'fpn_1xb2-ft_dawn-fog.py',
    'server_cbnet-revised': 'configs/pretrained/cbnet-revised-box_'
    'mobilenet-v2_nasfpn-crpn_1xb2-ft_dawn-fog.py',
}

#: ``--suite``: a named measurement, its settings as defaults (any option
#: given on the command line still wins).
SUITES = {
    # projects/edge_serving/README.md "The earlier edge model: FCOS-lite":
    # the edge model next to the server models like for like, as the edge
    # device runs them: one torch thread, 640x360 camera frames each
    # resized by its config's test pipeline (the edge model reads 320x180, the
    # servers 640x360), batch 1, inference only; the light head at 640 px
    # shows what the input size alone buys
    'edge': dict(
        models=['edge_fcos-lite_320', 'fcos-lite_640', 'server_cascade-rcnn',
                'server_cbnet-revised'],
        size=[360, 640], config_resize=True, batch_sizes=[1], repeats=20,
        warmup=2, no_train=True, scale_models=[], scale_sizes=[],
        scale_items=[],
        threads=1, reference='edge_fcos-lite_320',
        out_dir='work_dirs/benchmark_edge'),
}


def parse_size(text):
    """``'256x512'`` -> ``(256, 512)`` (height, width)."""
    try:
        h, w = (int(v) for v in text.lower().split('x'))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f'size {text!r} is not HEIGHTxWIDTH, e.g. 512x1024')
    return h, w


def parse_args(argv=None):
    p = argparse.ArgumentParser(
        description='CBNet vs baselines: speed, memory, FLOPs, scaling')
    p.add_argument('--suite', choices=sorted(SUITES),
                   help='a named measurement whose settings become the '
                   'defaults: ' + '; '.join(
                       f'{k}: {v}' for k, v in SUITES.items()))
    p.add_argument('--config-resize', action='store_true',
                   help='read --size as a camera frame that each model '
                   'gets resized as its config\'s test pipeline resizes '
                   'it (MMDet\'s inference API, the serving code); '
                   'default: every model gets --size as it is')
    p.add_argument('--image', default=None,
                   help='a photo (any size) resized to --size as the '
                   'input frame, instead of random pixels')
    p.add_argument('--checkpoint', nargs=2, action='append', default=[],
                   metavar=('NAME', 'FILE'),
                   help='trained weights of one model (strict load), so '
                   'detections and proposals are the trained model\'s '
                   '(repeatable); default: random weights')
    p.add_argument('--reference', default=REFERENCE,
                   help='the model of the ratio columns')
    p.add_argument('--models', nargs='+', default=list(MODELS),
                   help=f'names from {list(MODELS)} or NAME=CONFIG')
    p.add_argument('--size', type=int, nargs=2, default=[128, 256],
                   metavar=('H', 'W'), help='input height, width (pixels)')
    p.add_argument('--batch-sizes', type=int, nargs='+', default=[1, 4])
    p.add_argument('--repeats', type=int, default=2,
                   help='timed calls per measurement')
    p.add_argument('--warmup', type=int, default=1)
    p.add_argument('--num-items', type=int, default=8,
                   help='ground-truth instances per image (training)')
    p.add_argument('--proposals', choices=['fixed', 'model'],
                   default='fixed',
                   help='inference RoI heads run on a fixed, realistic '
                   'proposal set, the same for every model, as many as '
                   'its test_cfg.rpn.max_per_img (default; '
                   'cbnet_lab.benchmark.realistic_proposals), or '
                   'on what each random-weight RPN proposes')
    p.add_argument('--train-batch-size', type=int, default=1,
                   help='images per timed training step')
    p.add_argument('--model-cfg', nargs='+', action='append', default=[],
                   metavar=('NAME', 'KEY=VALUE'),
                   help='config overrides of one model, e.g. --model-cfg '
                   'b5_cells model.neck.fine_path=cells (repeatable; with '
                   '--models b5_cells=cbnet_mit-b5 the same config twice)')
    p.add_argument('--no-train', action='store_true')
    p.add_argument('--no-infer', action='store_true',
                   help='skip the inference measurements (--batch-sizes)')
    p.add_argument('--no-flops', action='store_true')
    p.add_argument('--scale-models', nargs='*',
                   default=['cbnet_mit-b0', REFERENCE])
    p.add_argument('--scale-sizes', type=parse_size, nargs='*',
                   default=[(128, 256), (256, 512)])
    p.add_argument('--scale-items', type=int, nargs='*',
                   default=[1, 32])
    p.add_argument('--device', default='cpu')
    p.add_argument('--amp', action='store_true',
                   help='fp16 autocast + AmpOptimWrapper (CUDA only)')
    p.add_argument('--threads', type=int, default=None,
                   help='torch intra-op threads (torch.set_num_threads); '
                   'default: torch\'s own setting. On a shared CPU use 1 '
                   '(and OMP_NUM_THREADS=1): spinning OpenMP threads make '
                   'ops several times slower under load')
    p.add_argument('--out-dir', default='work_dirs/benchmark')
    known, _ = p.parse_known_args(argv)
    if known.suite:
        p.set_defaults(**SUITES[known.suite])
    args = p.parse_args(argv)
    if args.amp and not args.device.startswith('cuda'):
        p.error('--amp needs a CUDA --device')
    if args.threads is not None and args.threads < 1:
        p.error('--threads must be at least 1')
    if args.train_batch_size < 1:
        p.error('--train-batch-size must be at least 1')
    configs = {}
    for item in args.models:
        name, _, path = item.partition('=')
        if not path or path in MODELS:
            key = path or name
            if key not in MODELS:
                p.error(f'unknown model {key!r}; known: {list(MODELS)} '
                        f'(or pass NAME=CONFIG)')
            path = osp.join(ROOT, MODELS[key])
        if not osp.isfile(path):
            p.error(f'config of {name!r} not found: {path}')
        configs[name] = path
    args.configs = configs
    args.overrides = {}
    for name, *pairs in args.model_cfg:
        if name not in configs:
            p.error(f'--model-cfg {name}: not one of --models {list(configs)}')
        for pair in pairs:
            key, sep, value = pair.partition('=')
            if not sep or not key:
                p.error(f'--model-cfg {name}: {pair!r} is not KEY=VALUE')
            args.overrides.setdefault(name, {})[key] = value
    args.scale_models = [m for m in args.scale_models if m in configs]
    if min(args.size) < 1:
        p.error(f'--size must be two positive integers (H W), got '
                f'{args.size}')
    args.checkpoints = {}
    for name, path in args.checkpoint:
        if name not in configs:
            p.error(f'--checkpoint {name}: not one of --models '
                    f'{list(configs)}')
        if not osp.isfile(path):
            p.error(f'--checkpoint {name}: no such file {path}')
        args.checkpoints[name] = path
    return args


def run(args, checkpoint=lambda results, scaling: None):
    """:func:`cbnet_lab.model_benchmark.run`, config paths relative to the
    repository."""
    return model_benchmark.run(args, checkpoint, root=ROOT)


def main(argv=None):
    args = parse_args(argv)
    from cbnet_lab.benchmark import set_malloc_thresholds

    # every timed call sees glibc's steady allocator, whether or not a
    # memory measurement (which lowers the mmap threshold) came before it
    set_malloc_thresholds()
    if args.threads is not None:
        import torch
        torch.set_num_threads(args.threads)
    start, load_start = time.time(), load_average()
    date = datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')
    omp = os.environ.get('OMP_NUM_THREADS')

    def record(results, scaling, partial):
        meta = dict(
            suite=args.suite, config_resize=args.config_resize,
            image=args.image, reference=args.reference,
            size=args.size, batch_sizes=args.batch_sizes,
            repeats=args.repeats, proposals=args.proposals,
            train_batch_size=args.train_batch_size,
            overrides=args.overrides, warmup=args.warmup,
            num_items=args.num_items, machine=machine(args), date=date,
            load_start=load_start, load_end=load_average(),
            command=(f'OMP_NUM_THREADS={omp} ' if omp else '') +
            'python tools/analysis_tools/benchmark.py ' +
            ' '.join(sys.argv[1:] if argv is None else argv),
            wall_s=time.time() - start,
            peak_memory=peak_memory_method(args.device), partial=partial)
        os.makedirs(args.out_dir, exist_ok=True)
        text = markdown(meta, results, scaling)
        with open(osp.join(args.out_dir, 'benchmark.json'), 'w') as f:
            json.dump(dict(meta=meta, results=results, scaling=scaling), f,
                      indent=2)
        with open(osp.join(args.out_dir, 'benchmark.md'), 'w') as f:
            f.write(text)
        return meta, text

    results, scaling = run(
        args, lambda res, sca: record(res, sca, partial=True))
    meta, text = record(results, scaling, partial=False)
    if scaling['sizes'] or scaling['items']:
        plot(scaling, osp.join(args.out_dir, 'scaling.png'))
    print(text)
    print(f'written {args.out_dir}/benchmark.{{json,md}} '
          f'({meta["wall_s"]:.0f} s)')


if __name__ == '__main__':
    main()
