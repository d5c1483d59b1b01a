"""Corruption robustness (mPC, rPC) next to the Foggy Cityscapes beta sweep.

The corruption benchmark of Michaelis et al. (2019) as MMDetection runs it
(``tools/analysis_tools/test_robustness.py`` and ``robustness_eval.py`` of
MMDetection, OpenMMLab, Apache-2.0): MMDet's ``Corrupt`` transform
(``imagecorruptions``) is inserted right after the image loader of the
test pipeline, every corruption is tested at severities 1-5 and the clean
images once (severity 0), and

* ``P``: the metric on clean data,
* ``mPC``: its mean over corruptions and severities 1-5,
* ``rPC = mPC / P``.

Results are stored exactly as MMDet's tool stores them
(``{corruption: {severity: {metric_key: value}}}``, pickled), so MMDet's
``robustness_eval.py`` reads our file. Differences from MMDet's tool: the
checkpoint is loaded by a test-only runner per condition (no
``model.backbone.init_cfg`` is needed, so CBNet-DD's ``CBNetDistiller``
works), the corruptions are applied to the clear images of a Foggy
Cityscapes config too, and the physical fog of Foggy Cityscapes (beta
sweep, :mod:`cbnet_lab.ap_drop`) is evaluated alongside.

Like MMDet's benchmark the images are corrupted in the loader's channel
order (BGR by default) although ``imagecorruptions`` assumes RGB: the same
images MMDet's published robustness numbers were computed on (fog is
channel-symmetric; ``brightness``/``saturate``/``frost`` are not).
"""
from typing import Callable, Dict, List, Optional, Sequence

import numpy as np

from cbnet_tools.markdown import markdown_table

from .ap_drop import evaluate
from .metric_keys import columns

#: Corruption groups, named and ordered as in MMDet's test_robustness.py
#: (``benchmark``: the 15 of the benchmark; ``all`` adds the 4 hold-out).
CORRUPTION_GROUPS = {
    'noise': ['gaussian_noise', 'shot_noise', 'impulse_noise'],
    'blur': ['defocus_blur', 'glass_blur', 'motion_blur', 'zoom_blur'],
    'weather': ['snow', 'frost', 'fog', 'brightness'],
    'digital':
    ['contrast', 'elastic_transform', 'pixelate', 'jpeg_compression'],
    'holdout': ['speckle_noise', 'gaussian_blur', 'spatter', 'saturate'],
}
CORRUPTION_GROUPS['benchmark'] = (
    CORRUPTION_GROUPS['noise'] + CORRUPTION_GROUPS['blur'] +
    CORRUPTION_GROUPS['weather'] + CORRUPTION_GROUPS['digital'])
CORRUPTION_GROUPS['all'] = (
    CORRUPTION_GROUPS['benchmark'] + CORRUPTION_GROUPS['holdout'])
#: How many leading corruptions ``aggregate='benchmark'`` averages (MMDet).
NUM_BENCHMARK = 15
#: Metric keys summarised: (label, key of CocoMetric / our mIoU metric).
SUMMARY_METRICS = tuple(
    (label, key) for label, key, _ in columns('box AP', 'mask AP', 'mIoU'))


def resolve_corruptions(names: Sequence[str]) -> List[str]:
    """Expand group names (``weather``, ``benchmark`` ...) in order.

    Args:
        names (Sequence[str]): Corruption or group names.

    Returns:
        list[str]: Corruption names, without repeats.

    Raises:
        ValueError: an unknown name.
    """
    known = set(CORRUPTION_GROUPS['all'])
    out: List[str] = []
    for name in names:
        group = CORRUPTION_GROUPS.get(name, [name])
        for corruption in group:
            if corruption not in known:
                raise ValueError(
                    f'unknown corruption {corruption!r}; known: '
                    f'{sorted(known)} or groups {sorted(CORRUPTION_GROUPS)}')
            if corruption not in out:
                out.append(corruption)
    return out


def check_corruptions(names: Sequence[str]) -> None:
    """Run each corruption once on a small image; fail before testing.

    ``imagecorruptions`` 1.1.2 calls ``skimage.filters.gaussian`` with
    ``multichannel=``, which scikit-image 0.20 removed, so ``glass_blur``
    and ``gaussian_blur`` fail with the scikit-image versions Python 3.11
    can install; without this check the error would surface from inside
    the test dataloader, after the runs before it.

    Args:
        names (Sequence[str]): Corruption names.

    Raises:
        RuntimeError: ``imagecorruptions`` is not installed.
        ValueError: naming every corruption that fails, with its error.
    """
    try:
        from imagecorruptions import corrupt
    except ImportError as err:
        raise RuntimeError(
            'the corruption benchmark needs imagecorruptions: pip install '
            'imagecorruptions==1.1.2 (requirements/runtime.txt)') from err
    img = np.full((32, 32, 3), 128, np.uint8)
    failed = []
    for name in names:
        try:
            corrupt(img, corruption_name=name, severity=1)
        except Exception as err:  # noqa: B902  (any library error)
            failed.append(f'{name}: {type(err).__name__}: {err}')
    if failed:
        raise ValueError(
            'these corruptions cannot run with the installed '
            'imagecorruptions / scikit-image (leave them out of '
            '--corruptions; docs/robustness.md):\n  ' + '\n  '.join(failed))


def run_benchmark(cfgs: dict,
                  log: Callable[[str], None] = print) -> dict:
    """Test a checkpoint under corruptions and under Foggy Cityscapes fog.

    Args:
        cfgs (dict): The finished test configs
            (:func:`cbnet_lab.config_edits.robustness_cfgs`: ``clean``,
            ``corrupted``, ``foggy``).
        log (callable): Progress messages.

    Returns:
        dict: ``corruptions``: MMDet's ``{corruption: {severity:
        metrics}}``; ``betas``: ``{beta: metrics}`` with ``0.0`` for the
        clear images (the same run as severity 0 when both are asked).
    """
    corrupted, foggy = cfgs['corrupted'], cfgs['foggy']
    if any(s > 0 for severities in corrupted.values() for s in severities):
        check_corruptions(list(corrupted))
    total = int(cfgs['clean'] is not None) + len(foggy) + sum(
        c is not None for severities in corrupted.values()
        for c in severities.values())
    done = 0
    clean = None

    def step(what: str, cfg) -> dict:
        nonlocal done
        done += 1
        log(f'[{done}/{total}] {what}')
        return evaluate(cfg)

    def clean_run() -> dict:
        nonlocal clean
        if clean is None:
            clean = step('clean images', cfgs['clean'])
        return clean

    results: Dict[str, Dict[int, dict]] = {}
    for corruption, severities in corrupted.items():
        for severity, cfg in severities.items():
            results.setdefault(corruption, {})[severity] = clean_run() \
                if cfg is None else step(
                    f'{corruption} severity {severity}', cfg)
    sweep: Dict[float, dict] = {}
    if foggy:
        sweep[0.0] = clean_run()
        for beta, cfg in foggy.items():
            sweep[beta] = step(f'Foggy Cityscapes beta={beta}', cfg)
    return dict(corruptions=results, betas=sweep)


def summarize(results: Dict[str, Dict[int, dict]],
              key: str = 'coco/bbox_mAP',
              aggregate: str = 'benchmark') -> dict:
    """P, mPC and rPC of one metric, overall and per corruption/severity.

    Computed as MMDet's ``robustness_eval.get_coco_style_results``: ``P``
    is the first corruption's severity 0; ``mPC`` the mean over
    corruptions (the first :data:`NUM_BENCHMARK` in the results' order
    with ``aggregate='benchmark'``, all with ``'all'``) and severities
    1-5; ``rPC = mPC / P``. With all five severities run the numbers are
    MMDet's; with fewer, the mean is over those run (MMDet's would count
    the missing ones as 0).

    Args:
        results (dict): ``{corruption: {severity: metrics}}``.
        key (str): Metric key, e.g. ``'coco/segm_mAP'``.
        aggregate (str): ``'benchmark'`` or ``'all'``.

    Returns:
        dict: ``P``, ``mPC``, ``rPC`` (None when P is 0 or missing) and
        ``per_corruption``: ``{corruption: {'severities': {s: value},
        'mPC': mean of severities >= 1, 'rPC': that / P, 'rPC_severities':
        {s: value / P}}}``. Values are MMDet's fractions (not percent).

    Raises:
        ValueError: no clean (severity 0) result, a corruption without a
            severity >= 1, or an unknown ``aggregate``.
    """
    if aggregate not in ('benchmark', 'all'):
        raise ValueError(f"aggregate must be 'benchmark' or 'all', got "
                         f'{aggregate!r}')
    if not results or 0 not in next(iter(results.values())):
        raise ValueError('results need severity 0 (clean) for the first '
                         'corruption')
    p = float(next(iter(results.values()))[0][key])

    def ratio(value: float) -> Optional[float]:
        return value / p if p > 0 else None

    per: Dict[str, dict] = {}
    for corruption, by_severity in results.items():
        sev = {
            int(s): float(m[key])
            for s, m in sorted(by_severity.items()) if s > 0
        }
        if not sev:
            raise ValueError(f'{corruption}: no severity >= 1 in results')
        mean = float(np.mean(list(sev.values())))
        per[corruption] = dict(
            severities=sev, mPC=mean, rPC=ratio(mean),
            rPC_severities={s: ratio(v) for s, v in sev.items()})
    used = list(per)[:NUM_BENCHMARK] if aggregate == 'benchmark' \
        else list(per)
    values = [v for c in used for v in per[c]['severities'].values()]
    mpc = float(np.mean(values))
    return dict(key=key, P=p, mPC=mpc, rPC=ratio(mpc), per_corruption=per)


def to_markdown(summary: dict, label: str) -> str:
    """Markdown table of :func:`summarize`'s output, in percent."""

    def pct(v: Optional[float]) -> str:
        return '-' if v is None else f'{100 * v:.1f}'

    sevs = sorted({
        s
        for row in summary['per_corruption'].values()
        for s in row['severities']
    })
    head = ['corruption'] + [f'{label} s{s}' for s in sevs] + \
        ['mPC', 'rPC (%)']
    lines = [
        f'{label}: P = {pct(summary["P"])}, mPC = {pct(summary["mPC"])}, '
        f'rPC = {pct(summary["rPC"])} %', ''
    ] + markdown_table(head, [
        [corruption] + [pct(row['severities'].get(s)) for s in sevs] +
        [pct(row['mPC']), pct(row['rPC'])]
        for corruption, row in summary['per_corruption'].items()
    ])
    return '\n'.join(lines)


def plot_fog_density(run: dict, out_file: str, title: str = '') -> str:
    """AP against fog density: Foggy Cityscapes beta and ``fog`` severity.

    Args:
        run (dict): :func:`run_benchmark` output (uses ``betas`` and the
            ``fog`` entry of ``corruptions``, whichever exist).
        out_file (str): PNG path.
        title (str): Figure title (the model's name).

    Returns:
        str: ``out_file``.

    Raises:
        ValueError: neither a beta sweep nor fog results.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fog = run['corruptions'].get('fog', {})
    panels = [(run['betas'], 'Foggy Cityscapes beta (1/m)'),
              (fog, 'imagecorruptions fog severity')]
    panels = [(p, x) for p, x in panels if p]
    if not panels:
        raise ValueError('nothing to plot: no beta sweep and no fog results')
    fig, axes = plt.subplots(
        1, len(panels), figsize=(5 * len(panels), 3.6), sharey=True,
        squeeze=False)
    for ax, (points, xlabel) in zip(axes[0], panels):
        xs = sorted(points)
        for label, key in SUMMARY_METRICS:
            ys = [points[x].get(key) for x in xs]
            if all(y is not None and y >= 0 for y in ys):
                ax.plot(xs, [100 * y for y in ys], marker='o', label=label)
        ax.set_xlabel(xlabel)
        ax.set_xticks(xs)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel('metric (%)')
    axes[0][0].legend()
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out_file, dpi=100)
    plt.close(fig)
    return out_file
