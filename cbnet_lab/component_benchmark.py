"""Components of the model timed against what they replace, in
alternation on the same inputs (:func:`cbnet_lab.benchmark.time_alternately`):
the engines of three command lines under ``tools/analysis_tools/``, whose
docstrings document what is measured.

- Kernels (``benchmark_kernels.py``): the gather deformable convolution
  against mmcv's (and torchvision's) over the FPN levels of the Cascade
  RPN's stage 2, and the fused boundary loss against its autograd form;
  :func:`kernel_rows`, :func:`kernel_table`.
- Mask loss (``benchmark_mask_loss.py``): ``CBNetBoundaryAwareLoss``
  variants against MMDet's mask BCE, time and peak tensor memory;
  :func:`mask_loss_rows`, :func:`mask_loss_table`.
- Backbone (``benchmark_backbone.py``): ``CBNetMiT`` with ``ope`` against
  ``cspe`` (and query-chunked ``cspe``), one fresh process per arch;
  :func:`backbone_rows`, :func:`backbone_table`.
"""
import functools
import multiprocessing
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Callable, Dict, List, Optional, Sequence

import numpy as np
import torch
from mmdet.registry import MODELS
from torch.profiler import ProfilerActivity, profile

import cbnet_mmdet  # noqa: F401  (registers the components)
from cbnet_mmdet.models.layers.cbnet_deform_conv2d import \
    deform_conv2d as gather_deform_conv2d
from cbnet_mmdet.models.losses import boundary_loss_fused, boundary_ops
from cbnet_tools.markdown import markdown_table

from .benchmark import (PeakMemory, set_malloc_thresholds, summarize,
                        synchronize, time_alternately)

# -- kernels ------------------------------------------------------------------

#: the FPN levels of the Cascade RPN's stage 2 (P2-P6)
STRIDES = (4, 8, 16, 32, 64)


def stock_deform_ops() -> Dict[str, Callable]:
    """The stock deformable convolutions that import here."""
    ops = {}
    try:
        from mmcv.ops import deform_conv2d as mmcv_op
        ops['mmcv'] = lambda x, off, w: mmcv_op(x, off, w, 1, 1, 1, 1, 1)
    except (ImportError, OSError):
        pass
    try:
        from torchvision.ops import deform_conv2d as tv_op

        def tv(x, off, w):
            # torchvision's offsets are (dy, dx) per tap as mmcv's
            return tv_op(x, off, w, padding=1)

        ops['torchvision'] = tv
    except (ImportError, OSError, RuntimeError):
        pass
    return ops


def gather_deform_conv2d_3x3(x, off, w):
    return gather_deform_conv2d(x, off, w, padding=(1, 1))


def deform_inputs(size, channels, batch, device, grad, seed=0):
    """One (x, offset, weight) per FPN level of a ``size`` image."""
    gen = torch.Generator().manual_seed(seed)
    levels = []
    for stride in STRIDES:
        h, w = -(-size[0] // stride), -(-size[1] // stride)
        x = torch.randn(batch, channels, h, w, generator=gen)
        off = 2 * torch.randn(batch, 18, h, w, generator=gen)
        wt = 0.05 * torch.randn(channels, channels, 3, 3, generator=gen)
        levels.append([t.to(device).requires_grad_(grad) for t in
                       (x, off, wt)])
    return levels


def deform_case(op, levels, grad):
    """One Cascade-RPN stage-2 pass over all levels (with backward)."""

    def run():
        if not grad:
            with torch.no_grad():
                for x, off, w in levels:
                    op(x, off, w)
            return
        total = sum(op(x, off, w).float().square().mean()
                    for x, off, w in levels)
        total.backward()

    return run


def loss_inputs(rois, device, seed=0):
    gen = torch.Generator().manual_seed(seed)
    logits = torch.randn(rois * 8, 28, 28, generator=gen)
    targets = (torch.rand(rois, 28, 28, generator=gen) > 0.5).float()
    index = torch.arange(rois) * 8 + torch.randint(0, 8, (rois, ),
                                                   generator=gen)
    return (logits.to(device).requires_grad_(), targets.to(device),
            index.to(device))


def loss_case(fn, logits, targets, index):

    def run():
        fn(logits, targets, index=index, dist_stride=2).mean().backward()

    return run


def rows_of(kernel, setting, times, stock):
    base = summarize(times[stock])['median']
    rows = []
    for name, values in times.items():
        s = summarize(values)
        rows.append(dict(kernel=kernel, setting=setting, impl=name,
                         median_ms=1e3 * s['median'], iqr_ms=1e3 * s['iqr'],
                         vs_stock=s['median'] / base))
    return rows


def kernel_rows(sizes: Sequence[Sequence[int]], channels: int,
                rois: Sequence[int], repeats: int, device: str = 'cpu',
                on_rows: Optional[Callable[[List[dict]], None]] = None
                ) -> List[dict]:
    """Each kernel against its stock op: one row per implementation and
    setting (``median_ms``, ``iqr_ms``, ``vs_stock``).

    Args:
        sizes: Image sizes ``(H, W)`` of the deformable convolution.
        channels (int): Its input and output channels.
        rois (Sequence[int]): RoI counts of the boundary loss.
        repeats (int): Timed rounds (after one warm-up round).
        device (str): Torch device.
        on_rows (callable, optional): Called with each setting's rows as
            they are measured.

    Raises:
        ValueError: A size whose coarsest level is smaller than 3x3
            (mmcv's kernel, the baseline, refuses it), checked first.
        ImportError: mmcv's deformable convolution, the baseline, does
            not import.
    """
    for h, w in sizes:
        if -(-min(h, w) // STRIDES[-1]) < 3:
            raise ValueError(
                f'--size {h} {w}: the stride-{STRIDES[-1]} level would be '
                'smaller than 3x3, which mmcv\'s kernel (the baseline) '
                f'refuses; use at least {2 * STRIDES[-1] + 1} px on each '
                'side')
    stock = stock_deform_ops()
    if 'mmcv' not in stock:
        raise ImportError('mmcv.ops.deform_conv2d does not import: the '
                          'stock op is needed as the baseline')
    on_rows = on_rows or (lambda rows: None)
    rows = []
    for size in sizes:
        for grad, batch in ((False, 1), (True, 2)):
            levels = deform_inputs(size, channels, batch, device, grad)
            ops = dict(gather=gather_deform_conv2d_3x3, **stock)
            cases = {n: deform_case(op, levels, grad) for n, op in ops.items()}
            setting = (f'{size[0]}x{size[1]}, C={channels}, batch '
                       f'{batch}, ' + ('fwd+bwd' if grad else 'inference'))
            rows += rows_of('deform conv (CRPN stage 2, P2-P6)', setting,
                            time_alternately(cases, repeats, 1, device),
                            'mmcv')
            on_rows(rows[-len(ops):])
    for n in rois:
        inputs = loss_inputs(n, device)
        cases = {
            'fused': loss_case(boundary_loss_fused.boundary_loss, *inputs),
            'autograd': loss_case(boundary_ops.boundary_loss_autograd,
                                  *inputs),
        }
        rows += rows_of('boundary loss', f'{n} RoIs 28x28, fwd+bwd',
                        time_alternately(cases, repeats, 1, device),
                        'autograd')
        on_rows(rows[-2:])
    return rows


def kernel_table(rows: List[dict]) -> str:
    return '\n'.join(markdown_table(
        ['kernel', 'setting', 'impl', 'median ms', 'IQR ms', 'x stock'],
        [[r['kernel'], r['setting'], r['impl'], f"{r['median_ms']:.2f}",
          f"{r['iqr_ms']:.2f}", f"{r['vs_stock']:.2f}"] for r in rows]))


# -- mask loss ----------------------------------------------------------------

#: the mask losses compared; ``bce`` is the baseline
MASK_LOSSES = {
    'bce': dict(type='CrossEntropyLoss', use_mask=True, loss_weight=1.0),
    'shape': dict(type='CBNetBoundaryAwareLoss', use_edge=False),
    'bound': dict(type='CBNetBoundaryAwareLoss'),  # dist_stride=2
    'bound_exact': dict(type='CBNetBoundaryAwareLoss', dist_stride=1),
}


def mask_loss_inputs(num_rois, num_classes, size, device, seed=0):
    gen = torch.Generator().manual_seed(seed)
    pred = torch.randn(num_rois, num_classes, size, size, generator=gen)
    target = (torch.rand(num_rois, size, size, generator=gen) >
              0.5).float()
    label = torch.randint(0, num_classes, (num_rois, ), generator=gen)
    return (pred.to(device).requires_grad_(), target.to(device),
            label.to(device))


def loss_step(loss_fn, pred, target, label, device='cpu'):
    """One forward + backward; returns the seconds of the forward and of
    the whole step."""
    pred.grad = None
    synchronize(device)
    start = time.perf_counter()
    loss = loss_fn(pred, target, label)
    synchronize(device)
    forward = time.perf_counter() - start
    loss.backward()
    synchronize(device)
    return forward, time.perf_counter() - start


def time_mask_losses(num_rois, num_classes, size, repeats, device='cpu'):
    """Median and best seconds of one forward + backward, and median of
    the forward alone, per loss.

    The losses run interleaved, so that a change of machine load hits all
    of them alike; the best run is the least disturbed by other processes.
    """
    inputs = mask_loss_inputs(num_rois, num_classes, size, device)
    steps = {
        name: functools.partial(loss_step, MODELS.build(cfg), *inputs,
                                device=device)
        for name, cfg in MASK_LOSSES.items()
    }
    runs = time_alternately(steps, repeats, 1, device, self_timed=True)
    total = {n: summarize([t for _, t in v]) for n, v in runs.items()}
    forward = {n: summarize([f for f, _ in v]) for n, v in runs.items()}
    return ({n: s['median'] for n, s in total.items()},
            {n: s['min'] for n, s in total.items()},
            {n: s['median'] for n, s in forward.items()})


def mask_loss_peak_memory(name, num_rois, num_classes, size, device='cpu'):
    """Peak tensor memory (MiB) allocated during one forward + backward.

    CPU: replay of the torch profiler's per-op allocation/free events in
    time order; GPU: ``torch.cuda.max_memory_allocated``
    (:class:`cbnet_lab.benchmark.PeakMemory`). Memory that exists before
    the step (inputs, the loss module) is not counted; the gradient of
    ``pred`` is.
    """
    fn = MODELS.build(MASK_LOSSES[name])
    inputs = mask_loss_inputs(num_rois, num_classes, size, device)
    loss_step(fn, *inputs)  # warm-up
    inputs[0].grad = None
    if str(device).startswith('cuda'):
        with PeakMemory(device) as mem:
            loss_step(fn, *inputs)
        return mem.peak
    with profile(activities=[ProfilerActivity.CPU],
                 profile_memory=True) as prof:
        loss_step(fn, *inputs)
    events = sorted((e for e in prof.events()
                     if e.self_cpu_memory_usage != 0),
                    key=lambda e: e.time_range.start)
    usage = np.cumsum([e.self_cpu_memory_usage for e in events])
    return float(usage.max(initial=0)) / 2**20


def mask_loss_rows(rois: Sequence[int], num_classes: int = 8,
                   size: int = 28, repeats: int = 20,
                   device: str = 'cpu') -> List[dict]:
    """One row per RoI count: times (ms), best times, forward times, peak
    memory (MiB) and the ratios to ``bce``, per loss.

    Sets glibc's steady allocator first (as the model benchmark):
    otherwise the 25 MiB logits gradient is mapped and page-faulted anew
    in a varying share of the steps, the main source of the spread.
    """
    set_malloc_thresholds()
    rows = []
    for num_rois in rois:
        times, best, forward = time_mask_losses(num_rois, num_classes, size,
                                                repeats, device)
        mem = {
            name: mask_loss_peak_memory(name, num_rois, num_classes, size,
                                        device)
            for name in MASK_LOSSES
        }
        rows.append(dict(
            rois=num_rois,
            time_ms={k: v * 1e3 for k, v in times.items()},
            best_time_ms={k: v * 1e3 for k, v in best.items()},
            peak_mem_mib=mem,
            time_ratio_vs_bce={k: times[k] / times['bce'] for k in times},
            forward_time_ms={k: v * 1e3 for k, v in forward.items()},
            forward_time_ratio_vs_bce={
                k: forward[k] / forward['bce'] for k in forward},
            best_time_ratio_vs_bce={k: best[k] / best['bce'] for k in best}))
    return rows


def mask_loss_table(rows: List[dict]) -> str:
    names = list(MASK_LOSSES)
    return '\n'.join(markdown_table(['RoIs'] + names, [[r['rois']] + [
        f"{r['time_ms'][n]:.2f} ({r['time_ratio_vs_bce'][n]:.2f}, "
        f"{r['best_time_ratio_vs_bce'][n]:.2f}); "
        f"fwd {r['forward_time_ms'][n]:.2f} "
        f"({r['forward_time_ratio_vs_bce'][n]:.2f}); "
        f"{r['peak_mem_mib'][n]:.1f} MiB" for n in names
    ] for r in rows]))


# -- backbone -----------------------------------------------------------------


def measure_backbone(arch: str, pos: Sequence[str] = ('ope', 'cspe'),
                     size: Sequence[int] = (512, 1024), runs: int = 3,
                     threads: Optional[int] = None,
                     query_chunk: Optional[int] = None,
                     device: str = 'cpu') -> List[dict]:
    """One arch's ``pos`` variants, forwards in alternation, in this
    process: one record per variant.

    The ``cspe`` model loads the ``ope`` weights, its CSPE tables then
    randomised (so the term is not zero); ``query_chunk`` adds ``cspe``
    with ``attn_query_chunk`` (the same weights). Peak memory: one more,
    untimed forward of each (:class:`cbnet_lab.benchmark.PeakMemory`).
    """
    if threads:
        torch.set_num_threads(threads)
    torch.manual_seed(0)
    models = {}
    for p in pos:
        model = MODELS.build(
            dict(type='CBNetMiT', arch=arch, pos_encoding=p, init_cfg=None))
        model.init_weights()
        models[p] = model.eval()
    if 'ope' in models and 'cspe' in models:
        models['cspe'].load_state_dict(models['ope'].state_dict(),
                                       strict=False)
    for name, p in models.get('cspe', torch.nn.Module()).named_parameters():
        if name.endswith('cspe.table'):
            torch.nn.init.normal_(p, std=0.02)
    if query_chunk and 'cspe' in models:
        chunked = MODELS.build(
            dict(type='CBNetMiT', arch=arch, pos_encoding='cspe',
                 attn_query_chunk=query_chunk, init_cfg=None))
        chunked.load_state_dict(models['cspe'].state_dict())
        models[f'cspe, chunk {query_chunk}'] = chunked.eval()
    device = torch.device(device)
    if device.type == 'cuda':
        torch.backends.cudnn.benchmark = False  # same kernels every round
    models = {p: model.to(device) for p, model in models.items()}
    x = torch.randn(1, 3, *size, device=device)
    peaks = {p: [] for p in models}
    set_malloc_thresholds()  # the same allocator for every timed forward
    with torch.no_grad():
        times = time_alternately(
            {p: functools.partial(model, x) for p, model in models.items()},
            runs, 1, str(device))
        for p, model in models.items():  # memory: one more, untimed
            with PeakMemory(str(device)) as mem:
                model(x)
            peaks[p].append(mem.peak)
    return [
        dict(arch=arch, pos=p,
             params_m=sum(q.numel() for q in model.parameters()) / 1e6,
             time_s=statistics.median(times[p]), peak_mib=max(peaks[p]),
             threads=torch.get_num_threads(), device=str(device),
             times_s=times[p], peak_forward_mib=peaks[p])
        for p, model in models.items()
    ]


def backbone_rows(archs: Sequence[str], **kwargs) -> List[dict]:
    """:func:`measure_backbone` for each arch in a fresh process (spawned:
    each arch's memory is measured alone), then the ratios of each variant
    to ``ope`` of its arch: ``time_ratio`` (of the medians),
    ``round_time_ratio`` (median of the per-round ratios), ``mem_ratio``
    (None without ``ope``)."""
    results = []
    for arch in archs:
        with ProcessPoolExecutor(
                1, mp_context=multiprocessing.get_context('spawn')) as pool:
            rows = pool.submit(measure_backbone, arch, **kwargs).result()
        for row in rows:
            results.append(row)
            print(f'done {arch} {row["pos"]}: {row["time_s"]:.3f} s',
                  file=sys.stderr)
    by_key = {(r['arch'], r['pos']): r for r in results}
    for r in results:
        base = by_key.get((r['arch'], 'ope'))
        r['time_ratio'] = r['time_s'] / base['time_s'] if base else None
        r['round_time_ratio'] = statistics.median(
            a / b for a, b in zip(r['times_s'], base['times_s'])) \
            if base else None
        r['mem_ratio'] = r['peak_mib'] / base['peak_mib'] if base else None
    return results


def backbone_table(results: List[dict]) -> str:
    return '\n'.join(markdown_table(
        ['arch', 'pos', 'params (M)', 'time (s)', 'peak fwd mem (MiB)',
         'time / ope', 'per-round time / ope', 'mem / ope'],
        [[r['arch'], r['pos'], f'{r["params_m"]:.2f}', f'{r["time_s"]:.3f}',
          f'{r["peak_mib"]:.0f}'] +
         (['-'] * 3 if r['time_ratio'] is None else
          [f'{r["time_ratio"]:.2f}', f'{r["round_time_ratio"]:.2f}',
           f'{r["mem_ratio"]:.2f}']) for r in results]))
