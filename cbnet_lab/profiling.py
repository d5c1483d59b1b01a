"""Where a detector's time goes: timed calls and one ``torch.profiler``
call, with a profiler range around each of the detector's parts; the
engine of ``tools/analysis_tools/profile_model.py`` (which documents what
is measured).

:func:`build` makes the model and its calls (inference, a training step)
on the benchmark's synthetic batch (:mod:`cbnet_lab.benchmark`);
:func:`profile` times and profiles them; :func:`markdown` reports.
"""
import statistics
import time
from contextlib import nullcontext
from typing import Callable, Dict, Optional, Sequence, Tuple

from cbnet_tools.markdown import markdown_table

from . import benchmark as B
from .config_edits import load_benchmark_cfg
from .report import machine_line

#: the detector's top-level parts that get their own profiler range
PARTS = ('backbone', 'neck', 'rpn_head', 'roi_head', 'bbox_head')


class PartRanges:
    """Profiler ranges around the work of the detector's parts.

    Detectors call their heads through ``predict`` / ``loss`` /
    ``loss_and_predict`` as well as ``forward``, so those methods are
    wrapped on the instances (removed again by :meth:`remove`); a part's
    nested calls (``loss_and_predict`` -> ``forward``) get one range.
    """

    METHODS = ('forward', 'predict', 'loss', 'loss_and_predict')

    def __init__(self, model):
        self.patched = []
        for name in PARTS:
            module = getattr(model, name, None)
            if module is None:
                continue
            depth = [0]
            for meth in self.METHODS:
                if callable(getattr(module, meth, None)):
                    setattr(module, meth,
                            self._wrap(getattr(module, meth), name, depth))
                    self.patched.append((module, meth))

    @staticmethod
    def _wrap(fn, name, depth):
        from torch.profiler import record_function

        def wrapped(*args, **kwargs):
            if depth[0]:
                return fn(*args, **kwargs)
            depth[0] += 1
            try:
                with record_function(f'part::{name}'):
                    return fn(*args, **kwargs)
            finally:
                depth[0] -= 1

        return wrapped

    def remove(self):
        for module, meth in self.patched:
            delattr(module, meth)  # back to the class's method


def build(config: str,
          size: Sequence[int] = (128, 256),
          batch_size: int = 1,
          num_items: int = 8,
          mode: str = 'both',
          device: str = 'cpu',
          cfg_options: Optional[dict] = None,
          proposals: str = 'fixed') -> Tuple[object, Dict[str, Callable]]:
    """A config's model (random weights) and the calls to profile.

    Args:
        config (str): Config file.
        size (Sequence[int]): Input height and width, pixels.
        batch_size (int): Images per call.
        num_items (int): Ground-truth instances per image (training).
        mode (str): ``'infer'``, ``'train'`` or ``'both'``.
        device (str): Torch device.
        cfg_options (dict, optional): Config keys to override.
        proposals (str): Inference RoI heads on the benchmark's
            ``'fixed'``, realistic proposals or on the ``'model'``'s own.

    Returns:
        tuple: The model and ``{'infer': fn, 'train': fn}`` (those asked
        for); ``train`` is loss forward, backward and the config's own
        optimiser step, each in a profiler range.
    """
    import torch
    cfg = load_benchmark_cfg(config, cfg_options)
    model = B.build_detector(cfg).to(device)
    # the benchmark suite's inputs: 8 classes, as every shipped config
    raw = B.make_batch(batch_size, tuple(size), num_items,
                       with_mask=B.has_mask_head(model))
    calls = {}
    if mode in ('infer', 'both'):
        data = B.preprocess(model, raw, False)

        fixed = proposals == 'fixed'

        def infer():
            model.eval()
            with torch.no_grad(), \
                    B.FixedProposals(model) if fixed else nullcontext():
                model(**data, mode='predict')

        calls['infer'] = infer
    if mode in ('train', 'both'):
        from mmengine.optim import build_optim_wrapper
        from torch.profiler import record_function
        wrapper = build_optim_wrapper(model, cfg.optim_wrapper)
        train_data = B.preprocess(model, raw, True)

        def train():
            model.train()
            with record_function('part::loss_forward'):
                losses = model(**train_data, mode='loss')
                loss, _ = model.parse_losses(losses)
            with record_function('part::backward'):
                wrapper.backward(loss)
            with record_function('part::optimizer'):
                wrapper.step()
                wrapper.zero_grad()

        calls['train'] = train
    return model, calls


def profile_call(fn, device, top):
    """Profile one call of ``fn``: part times and the top operators."""
    import torch
    from torch.profiler import ProfilerActivity, profile
    activities = [ProfilerActivity.CPU]
    if str(device).startswith('cuda'):
        activities.append(ProfilerActivity.CUDA)
    B.synchronize(device)
    start = time.perf_counter()
    with profile(activities=activities) as prof:
        fn()
        B.synchronize(device)
    wall = time.perf_counter() - start
    events = prof.key_averages()
    parts = {
        e.key[len('part::'):]: e.cpu_time_total / 1e3
        for e in events if e.key.startswith('part::')
    }
    ops = [e for e in events if not e.key.startswith('part::')]
    total = sum(e.self_cpu_time_total for e in ops) / 1e3
    ops.sort(key=lambda e: e.self_cpu_time_total, reverse=True)
    top_ops = [
        dict(
            name=e.key,
            calls=e.count,
            self_ms=e.self_cpu_time_total / 1e3,
            share=e.self_cpu_time_total / 1e3 / total if total else 0.)
        for e in ops[:top]
    ]
    if torch.cuda.is_available() and str(device).startswith('cuda'):
        for row, e in zip(top_ops, ops):
            row['self_cuda_ms'] = getattr(e, 'self_device_time_total',
                                          0.) / 1e3
    return dict(
        profiled_wall_s=wall,
        self_cpu_total_ms=total,
        parts_ms=parts,
        top_ops=top_ops)


def profile(model, calls: Dict[str, Callable], warmup: int = 1,
            repeats: int = 3, device: str = 'cpu', top: int = 15) -> dict:
    """Per call: ``repeats`` un-profiled timed calls after ``warmup``
    (``wall_s``), then one profiled call with the parts' ranges on
    (:func:`profile_call`)."""
    results = {}
    for mode, fn in calls.items():
        print(f'[profile] {mode}: {warmup} warm-up + {repeats} '
              'timed call(s) + 1 profiled', flush=True)
        times = B.time_calls(fn, repeats, warmup, device)
        ranges = PartRanges(model)
        try:
            res = profile_call(fn, device, top)
        finally:
            ranges.remove()
        res['wall_s'] = times
        results[mode] = res
    return results


def markdown(meta: dict, results: dict) -> str:
    """The report: the command, date and machine (``meta['machine']``, a
    :func:`cbnet_lab.report.machine_info`), then per call its times, its
    parts and a table of its top operators."""
    mach = meta['machine']
    lines = [
        f'`{meta["command"]}`', '',
        f'- {meta["date"]}; {machine_line(mach)} (load at the start); '
        f'OMP_NUM_THREADS={mach["omp_num_threads"] or "unset"}', ''
    ]
    for mode, res in results.items():
        t = res['wall_s']
        lines += [
            f'### {mode}: median {statistics.median(t):.3f} s, min '
            f'{min(t):.3f} s over {len(t)} call(s); profiled call '
            f'{res["profiled_wall_s"]:.3f} s', '',
            'Parts (inclusive CPU ms): ' + ', '.join(
                f'{k} {v:.0f}' for k, v in res['parts_ms'].items()), ''
        ] + markdown_table(
            ['operator', 'calls', 'self CPU (ms)', 'share'],
            [[f'`{o["name"]}`', o['calls'], f'{o["self_ms"]:.1f}',
              f'{o["share"]:.1%}'] for o in res['top_ops']])
        lines.append('')
    return '\n'.join(lines)
