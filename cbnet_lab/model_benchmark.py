"""Speed, memory and FLOPs of several detectors in one run, measured in
alternation on the same synthetic inputs: the engine of
``tools/analysis_tools/benchmark.py`` (which documents what is measured and
how; the helpers it uses are :mod:`cbnet_lab.benchmark`).

:func:`run` takes the tool's parsed arguments and returns the results;
:func:`markdown` and :func:`plot` report them; :func:`machine` describes
where they were measured.
"""
import copy
import os.path as osp
import sys
from contextlib import nullcontext

from cbnet_tools.markdown import markdown_table

from .report import machine_info

#: how the inference RoI heads got their proposals, for the tables
PROPOSALS = dict(
    fixed='one fixed, realistic proposal set for every model '
    '(realistic_proposals), as many per image as its RPN keeps at test '
    'time (test_cfg.rpn.max_per_img: the top ones of the same 1000)',
    model="each model's own RPN's proposals")
#: the reference row of the ratios
REFERENCE = 'cascade-mask-rcnn_swin-s'


class Bench:
    """The built models and their measurement calls."""

    def __init__(self, args):
        import torch

        from cbnet_lab import benchmark as B
        self.B, self.torch, self.args = B, torch, args
        self.device = args.device
        self.models, self.optims = {}, {}
        # the input each model sees for a --size input (frame): the same,
        # or (--config-resize) what its test pipeline's Resize makes of it
        self.sizes = {}
        # --image: the photo as a --size frame (the frames of all models
        # are this one, resized as their pipelines would)
        self.frame = None
        if getattr(args, 'image', None):
            import mmcv
            if not osp.isfile(args.image):
                raise FileNotFoundError(f'--image {args.image}: no such file')
            photo = mmcv.imread(args.image)
            if photo is None:
                raise ValueError(f'--image {args.image}: not readable as '
                                 'an image')
            self.frame = B.resize_image(photo, tuple(args.size))
        from mmengine.config import DictAction

        from cbnet_lab.config_edits import load_benchmark_cfg
        for name, path in args.configs.items():
            # the overrides' values parsed as on MMEngine's command lines
            cfg = load_benchmark_cfg(path, {
                k: DictAction._parse_iterable(v)
                for k, v in (args.overrides.get(name) or {}).items()})
            self.sizes[name] = (
                B.pipeline_input_size(cfg, tuple(args.size))
                if getattr(args, 'config_resize', False)
                else tuple(args.size))
            model = B.build_detector(cfg).to(self.device)
            checkpoint = getattr(args, 'checkpoints', {}).get(name)
            if checkpoint:
                # trained weights (--checkpoint): detections and proposals
                # as the deployed model makes them; every key must match
                from mmengine.runner import load_checkpoint
                load_checkpoint(model, checkpoint, map_location=self.device,
                                strict=True, logger='silent')
            self.models[name] = model
            self.optims[name] = cfg.get('optim_wrapper')
            print(f'built {name}', file=sys.stderr)

    def autocast(self):
        torch = self.torch
        return torch.autocast('cuda', dtype=torch.float16,
                              enabled=self.args.amp)

    def batch(self, name, size=None, batch_size=1, num_items=None):
        """Inputs of ``name``: ``size`` (height, width), or by default the
        size the model sees for the run's ``--size`` (:attr:`sizes`); the
        ``--image`` photo resized to it, else random images."""
        model = self.models[name]
        return self.B.make_batch(
            batch_size, tuple(size or self.sizes[name]),
            num_items=num_items or self.args.num_items,
            with_mask=self.B.has_mask_head(model), image=self.frame)

    def predict_call(self, name, raw):
        model, torch = self.models[name], self.torch

        fixed = self.args.proposals == 'fixed'

        def call():
            model.eval()
            with torch.no_grad(), self.autocast(), \
                    self.B.FixedProposals(model) if fixed else nullcontext():
                model(**self.B.preprocess(model, raw, False),
                      mode='predict')

        return call

    def train_call(self, name, raw):
        from mmengine.optim import build_optim_wrapper

        from cbnet_lab.config_edits import timing_optim_cfg
        model = self.models[name]
        wrapper = build_optim_wrapper(
            model, timing_optim_cfg(self.optims[name], self.args.amp))

        def call():
            model.train()
            data = self.B.preprocess(model, raw, True)
            with self.autocast():
                self.B.train_step(model, data, wrapper)

        return call, wrapper

    def measure(self, calls, repeats, warmup, on_round=None):
        """Alternate ``calls`` (name -> fn, through
        :func:`cbnet_lab.benchmark.time_alternately`): ``repeats`` timed
        rounds after ``warmup`` untimed ones, then one more call of each
        for its peak memory (measuring memory changes how the allocator
        works, see ``PeakMemory``, so it is never timed).
        ``on_round(out)`` after every timed round: a run cut short (a time
        limit) keeps the rounds it finished.

        Besides the wall time, each timed call's CPU time of this process
        (``time.process_time``) is kept (``cpu_times``): on a shared CPU
        the wall time includes the time the scheduler gave other
        processes, the CPU time does not, so with one torch thread it
        estimates the latency on an idle core (caches and memory
        bandwidth stay shared).
        """
        import time
        B = self.B
        out = {n: dict(times=[], cpu_times=[], peak_mib=[]) for n in calls}
        cpu = {n: [] for n in calls}

        def cpu_timed(name, fn):
            def call():
                start = time.process_time()
                fn()
                cpu[name].append(time.process_time() - start)
            return call

        def round_done(i, times):
            for name in out:
                out[name]['times'] = times[name]
                # the warm-up rounds' calls came first
                out[name]['cpu_times'] = cpu[name][warmup:]
            print(f'round {i + 1}/{repeats}: ' + ', '.join(
                f'{n} {v["times"][-1]:.3f} s' for n, v in out.items()),
                  file=sys.stderr)
            if on_round is not None:
                on_round(out)

        B.time_alternately({n: cpu_timed(n, fn) for n, fn in calls.items()},
                           repeats, warmup, self.device,
                           on_round=round_done)
        for name, fn in calls.items():
            with B.PeakMemory(self.device) as mem:
                fn()
                B.synchronize(self.device)
            out[name]['peak_mib'].append(mem.peak)
        return out


def _peak(values):
    values = [v for v in values if v is not None]
    return max(values) if values else None


def run(args, checkpoint=lambda results, scaling: None, root=None):
    """Measure; ``checkpoint(results, scaling)`` after every timed round
    and phase, so a run killed later (out of memory in a training step, a
    time limit) keeps what it measured. Config paths are recorded relative
    to ``root`` (as given without it)."""
    bench = Bench(args)
    B, names = bench.B, list(bench.models)
    results = {
        n: dict(config=osp.relpath(args.configs[n], root)
                if root else args.configs[n],
                input_size=list(bench.sizes[n]))
        for n in names
    }
    for n, path in getattr(args, 'checkpoints', {}).items():
        results[n]['checkpoint'] = path
    for n in names:
        model = bench.models[n]
        results[n]['params_m'] = B.count_params(model) / 1e6
        results[n]['weights_mib'] = sum(
            p.numel() * p.element_size() for p in model.parameters()) / 2**20
        if args.proposals == 'fixed' and hasattr(model, 'rpn_head'):
            results[n]['test_proposals'] = B.FixedProposals(model).num
        if not args.no_flops:
            model.eval()
            raw = bench.batch(n)
            results[n]['gflops'] = B.count_flops(
                model, B.preprocess(model, raw, False))
        print(f'counted {n}', file=sys.stderr)
    for bs in [] if args.no_infer else args.batch_sizes:
        calls = {n: bench.predict_call(n, bench.batch(n, batch_size=bs))
                 for n in names}

        def keep(meas, bs=bs):
            for n in names:
                s = B.summarize(meas[n]['times'])
                cpu = B.summarize(meas[n]['cpu_times'])
                results[n].setdefault('inference', {})[str(bs)] = dict(
                    seconds=s, images_per_s=bs / s['median'],
                    cpu_seconds=cpu,
                    images_per_cpu_s=bs / cpu['median']
                    if cpu['median'] > 0 else None,
                    peak_mib=_peak(meas[n]['peak_mib']),
                    times=meas[n]['times'], cpu_times=meas[n]['cpu_times'])
            checkpoint(results, dict(sizes={}, items={}))

        keep(bench.measure(calls, args.repeats, args.warmup, on_round=keep))
        print(f'inference batch {bs} done', file=sys.stderr)
    if not args.no_train:
        # the timed training steps move the weights (lr 1e-8, but a random
        # model's proposal scores are near ties); the scaling study measures
        # inference again, so its models' weights are put back afterwards
        initial = {n: copy.deepcopy(bench.models[n].state_dict())
                   for n in args.scale_models if args.scale_sizes}
        calls, wrappers = {}, {}
        for n in names:
            calls[n], wrappers[n] = bench.train_call(
                n, bench.batch(n, batch_size=args.train_batch_size))

        def keep_train(meas):
            for n in names:
                results[n]['train_step'] = dict(
                    seconds=B.summarize(meas[n]['times']),
                    peak_mib=_peak(meas[n]['peak_mib']),
                    times=meas[n]['times'])
            checkpoint(results, dict(sizes={}, items={}))

        keep_train(bench.measure(calls, args.repeats, args.warmup,
                                 on_round=keep_train))
        del wrappers
        for n, state in initial.items():
            bench.models[n].load_state_dict(state)
        del initial
        print('training done', file=sys.stderr)
    scaling = dict(sizes={}, items={})
    for hw in args.scale_sizes:
        calls = {n: bench.predict_call(n, bench.batch(n, hw))
                 for n in args.scale_models}
        meas = bench.measure(calls, args.repeats, args.warmup)
        for n in args.scale_models:
            scaling['sizes'].setdefault(n, []).append(dict(
                size=list(hw),
                seconds=B.summarize(meas[n]['times'])['median'],
                peak_mib=_peak(meas[n]['peak_mib'])))
        print(f'scaling size {hw} done', file=sys.stderr)
        checkpoint(results, scaling)
    if not args.no_train:
        for k in args.scale_items:
            calls = {}
            for n in args.scale_models:
                calls[n], _ = bench.train_call(
                    n, bench.batch(n, batch_size=args.train_batch_size,
                                   num_items=k))
            meas = bench.measure(calls, args.repeats, args.warmup)
            for n in args.scale_models:
                scaling['items'].setdefault(n, []).append(dict(
                    num_items=k,
                    seconds=B.summarize(meas[n]['times'])['median'],
                    peak_mib=_peak(meas[n]['peak_mib'])))
            print(f'scaling items {k} done', file=sys.stderr)
    return results, scaling


def machine(args) -> dict:
    """The machine, thread count and software of the run
    (:func:`cbnet_lab.report.machine_info`) and whether AMP was on."""
    return dict(machine_info(args.device), amp=args.amp)


def _f(v, fmt='{:.3f}'):
    return '-' if v is None else fmt.format(v)


def peak_memory_method(device):
    """How :class:`PeakMemory` measures on ``device``, in words."""
    from cbnet_lab.benchmark import hwm_reset_works
    if str(device).startswith('cuda'):
        return 'torch.cuda.max_memory_allocated above the allocation at entry'
    if hwm_reset_works():
        return 'resident-set high-water mark (VmHWM, reset per call)'
    return ('resident set polled every 2 ms (this kernel does not keep '
            'VmHWM after a reset; a lower bound)')


def markdown(meta, results, scaling):
    """The tables of ``benchmark.md``."""
    # the model of the ratio columns (--reference); Swin-S, the heaviest
    # baseline, by default
    ref_name = meta.get('reference', REFERENCE)
    ref = results.get(ref_name)
    ref_label = 'Swin-S' if ref_name == REFERENCE else ref_name
    h, w = meta['size']
    mach = meta['machine']

    def load(key):
        v = meta.get(key)
        return '-' if not v else ' / '.join(f'{x:.2f}' for x in v)

    trained = sorted(n for n, r in results.items() if r.get('checkpoint'))
    if not trained:
        weights = 'random weights'
    elif len(trained) == len(results):
        weights = 'trained weights (checkpoints below)'
    else:
        weights = (f'trained weights for {", ".join(trained)} (checkpoints '
                   'below), random for the others')
    lines = [
        f'Input {h}x{w}, {meta["num_items"]} instances per image (training)'
        f', {meta["repeats"]} timed repeats after {meta["warmup"]} warm-up, '
        f'{weights}; inference RoI heads on '
        f'{PROPOSALS[meta.get("proposals", "model")]}.' +
        (' PARTIAL: the run stopped before its end; the missing cells were '
         'not measured.' if meta.get('partial') else ''), '',
        f'- command: `{meta["command"]}`',
        f'- date: {meta["date"]}, wall time {_f(meta.get("wall_s"), "{:.0f}")}'
        ' s',
        f'- machine: {mach["device"]}; {mach["platform"]}',
        f'- threads: torch {mach["threads"]}, OMP_NUM_THREADS='
        f'{mach["omp_num_threads"] or "unset"}',
        f'- load average (1 / 5 / 15 min): start {load("load_start")}, '
        f'end {load("load_end")}',
        f'- software: Python {mach["python"]}, torch {mach["torch"]}, mmcv '
        f'{mach["mmcv"]}, mmdet {mach["mmdet"]}; AMP {mach["amp"]}; '
        f'cbnet_mmdet from {mach.get("cbnet_mmdet", "-")}',
        f'- peak memory: {meta.get("peak_memory", "-")}',
    ] + ([
        f'- input: {h}x{w} frames, each resized as its config\'s test '
        'pipeline resizes (the `input` column: what the model saw, before '
        'padding)'
    ] if meta.get('config_resize') else []) + ([
        f'- image: `{meta["image"]}` resized to {h}x{w} (synthetic ground '
        'truth for training)'
    ] if meta.get('image') else []) + [
        f'- {name}: checkpoint `{r["checkpoint"]}`'
        for name, r in results.items() if r.get('checkpoint')
    ] + [
        f'- {name}: ' + ', '.join(f'`{k}={v}`' for k, v in opts.items())
        for name, opts in meta.get('overrides', {}).items()
    ] + ([
        '- proposals per image at test time: ' + ', '.join(
            f'{name} {r["test_proposals"]}' for name, r in results.items()
            if 'test_proposals' in r)
    ] if any('test_proposals' in r for r in results.values()) else []) + [
        ''
    ]

    def ratio(r, key):
        if ref is None:
            return None
        get = {
            'lat': lambda x: x.get('inference', {}).get('1', {}).get(
                'seconds', {}).get('median'),
            'train': lambda x: x.get('train_step', {}).get(
                'seconds', {}).get('median'),
            'params': lambda x: x['params_m'],
        }[key]
        a, b = get(r), get(ref)
        return a / b if a is not None and b else None

    frames = bool(meta.get('config_resize'))
    header = (['model', 'params (M)', 'GFLOPs infer / backbone+neck',
               'latency b1 (s, median / p95 [IQR])'] +
              [f'img/s b{b}' for b in meta['batch_sizes']] +
              [f'train step b{meta.get("train_batch_size", 1)} (s)',
               'peak mem infer / train (MiB)', f'latency / {ref_label}',
               f'train / {ref_label}', f'params / {ref_label}'] +
              (['CPU time b1 (s, median / p95)', 'img/s b1 by CPU time',
                'input (HxW)', 'weights (MiB)'] if frames else []))
    rows = []
    for name, r in results.items():
        # a --no-infer run, or one stopped before its first timed round
        inf = r.get('inference', {})
        lat = inf.get('1', next(iter(inf.values()), {})).get('seconds', {})
        cpu = inf.get('1', {}).get('cpu_seconds', {})
        fl = r.get('gflops', {})
        tr = r.get('train_step', {})
        rows.append(
            [name, f'{r["params_m"]:.1f}',
             f'{_f(fl.get("predict"), "{:.1f}")} / '
             f'{_f(fl.get("features"), "{:.1f}")}',
             f'{_f(lat.get("median"))} / {_f(lat.get("p95"))} '
             f'[{_f(lat.get("iqr"))}]'] +
            [_f(inf.get(str(b), {}).get('images_per_s'), '{:.2f}')
             for b in meta['batch_sizes']] +
            [_f(tr.get('seconds', {}).get('median')),
             f'{_f(inf.get("1", {}).get("peak_mib"), "{:.0f}")} / '
             f'{_f(tr.get("peak_mib"), "{:.0f}")}',
             _f(ratio(r, 'lat'), '{:.2f}'), _f(ratio(r, 'train'), '{:.2f}'),
             _f(ratio(r, 'params'), '{:.2f}')] +
            ([f'{_f(cpu.get("median"))} / {_f(cpu.get("p95"))}',
              _f(inf.get('1', {}).get('images_per_cpu_s'), '{:.2f}'),
              'x'.join(map(str, r.get('input_size', meta['size']))),
              _f(r.get('weights_mib'), '{:.0f}')] if frames else []))
    if not any('train_step' in r for r in results.values()):
        # an inference-only run (--no-train): no training columns
        keep = [i for i, h in enumerate(header)
                if not h.startswith('train ')]
        header = [header[i] for i in keep]
        rows = [[row[i] for i in keep] for row in rows]
    # a scaling-only run (--no-infer --no-train) has no row to show here
    if any('inference' in r or 'train_step' in r for r in results.values()):
        lines += markdown_table(header, rows)
    if scaling['sizes']:
        lines += [''] + markdown_table(
            ['model', 'input', 'latency b1 (s)', 'peak mem (MiB)'],
            [[name, f'{row["size"][0]}x{row["size"][1]}',
              f'{row["seconds"]:.3f}', _f(row['peak_mib'], '{:.0f}')]
             for name, rows in scaling['sizes'].items() for row in rows])
    if scaling['items']:
        lines += [''] + markdown_table(
            ['model', 'instances / image', 'train step (s)',
             'peak mem (MiB)'],
            [[name, row['num_items'], f'{row["seconds"]:.3f}',
              _f(row['peak_mib'], '{:.0f}')]
             for name, rows in scaling['items'].items() for row in rows])
    return '\n'.join(lines) + '\n'


def plot(scaling, path):
    """Latency vs input pixels and train step vs instances, one PNG with
    a panel for each that was measured (a run that timed only one of them
    gets one panel, never an empty one).

    Raises:
        ValueError: nothing was measured.
    """
    panels = [(key, xlabel, ylabel, title, x)
              for key, xlabel, ylabel, title, x in (
                  ('sizes', 'input (megapixels)', 'latency b1 (s)',
                   'inference vs input size',
                   lambda r: r['size'][0] * r['size'][1] / 1e6),
                  ('items', 'ground-truth instances / image',
                   'train step (s)', 'training vs instances',
                   lambda r: r['num_items'])) if scaling.get(key)]
    if not panels:
        raise ValueError('no scaling measurement to plot')
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4),
                             squeeze=False)
    for ax, (key, xlabel, ylabel, title, x) in zip(axes[0], panels):
        for name, rows in scaling[key].items():
            ax.plot([x(r) for r in rows], [r['seconds'] for r in rows],
                    'o-', label=name)
        ax.set(xlabel=xlabel, ylabel=ylabel, title=title)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
