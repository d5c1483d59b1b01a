"""Reporting for the lab: the tables and plots of a comparison, and the
machine a measurement ran on, written once for every tool and record.

Every markdown table goes through :func:`cbnet_tools.markdown_table`.
"""
import os
import os.path as osp
import platform
from typing import List, Optional, Sequence

from cbnet_tools.markdown import markdown_table


def load_average() -> Optional[List[float]]:
    """1-, 5- and 15-minute load averages, or ``None`` (no ``getloadavg``)."""
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def machine_info(device: str = 'cpu') -> dict:
    """The machine, thread count and software a measurement ran with.

    Args:
        device (str): The torch device measured (``'cpu'``, ``'cuda:0'``).

    Returns:
        dict: ``platform``, ``system`` (``Linux``...), ``processor``,
        ``cpu_count``, ``threads`` (torch intra-op), ``omp_num_threads``,
        ``python``, ``torch``, ``mmcv``, ``mmdet``, ``cbnet_mmdet`` (the
        folder of the copy that ran: installed, or a checkout on
        ``PYTHONPATH``), ``loadavg`` and ``device`` (a CPU description;
        on a GPU, its name first, then the CPU, which feeds it).
    """
    import mmcv
    import mmdet
    import torch

    import cbnet_mmdet
    info = dict(
        platform=platform.platform(),
        system=platform.system(),
        processor=platform.processor() or platform.machine(),
        cpu_count=os.cpu_count(),
        threads=torch.get_num_threads(),
        omp_num_threads=os.environ.get('OMP_NUM_THREADS'),
        python=platform.python_version(),
        torch=torch.__version__,
        mmcv=mmcv.__version__,
        mmdet=mmdet.__version__,
        cbnet_mmdet=osp.dirname(cbnet_mmdet.__file__),
        loadavg=load_average())
    info['device'] = (f'CPU {info["processor"]}, {info["cpu_count"]} '
                      f'cores, {info["threads"]} torch threads')
    if str(device).startswith('cuda'):
        info['device'] = (f'{torch.cuda.get_device_name(device)} + '
                          f'{info["device"]}')
    return info


def machine_line(info: Optional[dict] = None, device: str = 'cpu') -> str:
    """:func:`machine_info` as one line (records, table captions).

    Args:
        info (dict, optional): A :func:`machine_info` result; None measures
            this machine.
        device (str): The torch device measured, when ``info`` is None.
    """
    info = machine_info(device) if info is None else info
    line = (f'{info["device"]}, {info["system"]}, torch {info["torch"]}, '
            f'mmdet {info["mmdet"]}')
    if info.get('loadavg'):
        line += ', load ' + ' / '.join(f'{v:.2f}' for v in info['loadavg'])
    return line


def _cell(stat: Optional[dict]) -> str:
    if stat is None:
        return '-'
    if stat['n'] > 1:
        return f"{stat['mean']:.1f} +- {stat['std']:.1f}"
    return f"{stat['mean']:.1f}"


def to_markdown(summary: dict) -> str:
    """Markdown tables of :func:`summarize`: one per condition.

    Clear val: every column and the training time. Foggy val: every column
    and the drop of each from clear (clear - foggy; positive = worse in
    fog). Cells are ``mean +- std`` over seeds (std of the sample).
    """
    cols = summary['columns']
    out = []
    for condition in summary['conditions']:
        foggy = condition != summary['conditions'][0]
        heads = cols + ([f'{c} drop' for c in cols] if foggy
                        else ['train time (s)'])
        out.append(f'**{condition}**\n')
        rows = []
        for recipe in summary['recipes']:
            entry = summary['summary'][recipe]
            cells = [_cell(entry[condition].get(h)) for h in heads] \
                if foggy else \
                [_cell(entry[condition].get(h)) for h in cols] + \
                [_cell(entry['train time (s)'])]
            rows.append([recipe] + cells)
        out += markdown_table(['recipe'] + heads, rows)
        out.append('')
    return '\n'.join(out)


def plot(summary: dict, betas: Sequence[float], path: str,
         column: Optional[str] = None) -> str:
    """AP (or AR) vs fog density per recipe, mean +- std over seeds.

    With no fog density (real data), a bar per recipe on the last
    condition: the only one, or a second test set (a set's
    ``transfer_test``: real fog after clear training). With fog densities
    and a second test set after them (real fog after training on generated
    scenes), the curve and, beside it, those bars.

    Args:
        summary (dict): :func:`summarize` output.
        betas (Sequence[float]): Fog densities; clear is drawn at 0.
        path (str): Output image (PNG).
        column (str, optional): Column to draw; default mask AP when
            every recipe reports it, else box AP (a box-only detector in
            the set), else the last column (AR@1000 for proposals).

    Returns:
        str: ``path``.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    cols = summary['columns']
    reference = summary['conditions'][0]
    if column is None:
        clear = [summary['summary'][r][reference]
                 for r in summary['recipes']]
        column = next((c for c in ('mask AP', 'box AP') if c in cols and
                       all(e.get(c) is not None for e in clear)), cols[-1])
    xs = [0.0] + list(betas)
    # the curve over clear and the densities; bars on the last condition
    # when there is no density (real data) or a second test set follows
    curve = bool(betas)
    bars = not betas or len(summary['conditions']) > len(xs)
    if curve and bars:
        fig, (curve_ax, bar_ax) = plt.subplots(
            1, 2, figsize=(10, 3.8), gridspec_kw=dict(width_ratios=[3, 2]))
    else:
        fig, curve_ax = plt.subplots(figsize=(5.5, 3.8))
        bar_ax = curve_ax
    if bars:
        _bars(bar_ax, summary, summary['conditions'][-1], column)
    if curve:
        _curve(curve_ax, summary, xs, column)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _curve(ax, summary: dict, xs: Sequence[float], column: str) -> None:
    """``column`` (mean +- std) per recipe against the fog density ``xs``
    (clear at 0), over the first ``len(xs)`` conditions."""
    for recipe in summary['recipes']:
        entry = summary['summary'][recipe]
        stats = [entry[c].get(column) for c in summary['conditions']]
        pts = [(x, s) for x, s in zip(xs, stats) if s is not None]
        if not pts:
            continue
        ax.errorbar([p[0] for p in pts], [p[1]['mean'] for p in pts],
                    yerr=[p[1]['std'] for p in pts], marker='o', capsize=3,
                    label=recipe)
    # ticks at the tested densities only (matplotlib's own run together)
    ax.set_xticks(xs)
    ax.set_xticklabels([f'{x:g}' for x in xs])
    ax.set_xlabel('fog density beta (1/m; 0 = clear)')
    ax.set_ylabel(f'{column} (%)')
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def _bars(ax, summary: dict, condition: str, column: str) -> None:
    """Bars of ``column`` (mean +- std) per recipe on ``condition``."""
    recipes = summary['recipes']
    stats = [summary['summary'][r][condition].get(column) for r in recipes]
    ax.bar(range(len(recipes)), [s['mean'] if s else 0.0 for s in stats],
           yerr=[s['std'] if s else 0.0 for s in stats], capsize=3,
           color=[f'C{i}' for i in range(len(recipes))])
    ax.set_xticks(range(len(recipes)))
    ax.set_xticklabels(recipes, rotation=30, ha='right', fontsize=8)
    ax.set_ylabel(f'{column} (%) on {condition}')
    ax.grid(alpha=0.3, axis='y')
