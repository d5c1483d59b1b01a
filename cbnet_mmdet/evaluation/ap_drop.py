"""AP drop from Cityscapes to Foggy Cityscapes (the paper's Table 2).

One checkpoint is tested on the clear val images and on the foggy ones
(per beta) with the same annotations, through MMEngine's ``Runner.test``;
only ``test_dataloader.dataset`` changes between runs. Used by
``tools/analysis_tools/ap_drop.py`` and importable by demos.
"""
import copy
import os.path as osp
from typing import Dict, List, Optional, Sequence

from mmengine.config import Config
from mmengine.runner import Runner

from ..utils.checkpoint_fit import require_checkpoint_fit

CLEAR_TYPES = ('CityscapesDataset', 'CBNetCityscapesDataset')
FOGGY_TYPE = 'CBNetFoggyCityscapesDataset'

#: Table columns: (name, metric key, scale). Metrics from ``CocoMetric``
#: (prefix ``coco``) and ``CBNetInstanceMIoUMetric`` (``cityscapes``),
#: reported in percent like the paper.
COLUMNS = (
    ('box AP', 'coco/bbox_mAP', 100.0),
    ('mask AP', 'coco/segm_mAP', 100.0),
    ('mask AP50', 'coco/segm_mAP_50', 100.0),
    ('mIoU', 'cityscapes/mIoU', 100.0),
)
#: Columns whose drop (clear minus foggy) is reported.
DROP_COLUMNS = ('box AP', 'mask AP', 'mIoU')


def condition_cfg(cfg: Config, beta: Optional[float] = None) -> Config:
    """Copy of ``cfg`` testing clear images (``beta=None``) or foggy ones.

    Args:
        cfg (Config): A config whose ``test_dataloader.dataset`` is a
            (CBNet) Cityscapes or Foggy Cityscapes dataset.
        beta (float, optional): Fog attenuation coefficient, 1/m.

    Returns:
        Config: The modified copy.
    """
    cfg = copy.deepcopy(cfg)
    ds = cfg.test_dataloader.dataset
    if ds.type not in CLEAR_TYPES + (FOGGY_TYPE, ):
        raise ValueError(
            f'test_dataloader.dataset.type must be one of '
            f'{CLEAR_TYPES + (FOGGY_TYPE, )}, got {ds.type!r}')
    if beta is None:
        if ds.type == FOGGY_TYPE:
            ds.type = 'CBNetCityscapesDataset'
            ds.pop('beta', None)
    else:
        ds.type = FOGGY_TYPE
        ds.beta = beta
    return cfg


def evaluate_condition(cfg: Config, checkpoint: str, work_dir: str,
                       beta: Optional[float] = None) -> Dict[str, float]:
    """Test ``checkpoint`` on clear (``beta=None``) or foggy val.

    Args:
        cfg (Config): Test config (model, test dataloader and evaluator).
        checkpoint (str): Checkpoint file.
        work_dir (str): Runner work folder (logs of each condition go to a
            sub-folder).
        beta (float, optional): Fog attenuation coefficient, 1/m.

    Returns:
        dict[str, float]: The evaluators' metrics.
    """
    name = 'clear' if beta is None else f'foggy_beta_{beta}'
    return evaluate_checkpoint(condition_cfg(cfg, beta), checkpoint,
                               work_dir, name, prefix='ap_drop')


def evaluate_checkpoint(cfg: Config, checkpoint: str, work_dir: str,
                        name: str, prefix: str = 'test') -> Dict[str, float]:
    """``Runner.test`` of ``checkpoint`` with a test-only copy of ``cfg``.

    Args:
        cfg (Config): Test config (model, test dataloader and evaluator).
        checkpoint (str): Checkpoint file.
        work_dir (str): Runner work folder; the logs go to
            ``{work_dir}/{name}``.
        name (str): Name of this run (sub-folder, experiment name).
        prefix (str): Experiment name prefix.

    Returns:
        dict[str, float]: The evaluators' metrics.
    """
    cfg = copy.deepcopy(cfg)
    cfg.load_from = checkpoint
    require_checkpoint_fit(cfg)  # refuse a checkpoint of another model
    cfg.work_dir = osp.join(work_dir, name)
    # unique per run and condition: MMEngine keys its logger and message
    # hub by this name, and a process may test several checkpoints
    cfg.experiment_name = f"{cfg.get('experiment_name') or prefix}_{name}"
    cfg.pop('resume', None)
    # a test-only runner: nothing of training or validation is built
    for key in ('train_dataloader', 'train_cfg', 'optim_wrapper',
                'param_scheduler', 'val_dataloader', 'val_cfg',
                'val_evaluator'):
        cfg.pop(key, None)
    return Runner.from_cfg(cfg).test()


def drop_table(metrics: Dict[str, Dict[str, float]]) -> dict:
    """Table 2 rows from the metrics of each condition.

    Args:
        metrics (dict): Metrics per condition name; the first one is the
            reference (clear).

    Returns:
        dict: ``{'columns': [...], 'rows': [{'condition', <column>...,
        '<column> drop'...}]}``, values in percent (None if the metric is
        missing).
    """
    rows: List[dict] = []
    ref = None
    for condition, m in metrics.items():
        row = {'condition': condition}
        for col, key, scale in COLUMNS:
            val = m.get(key)
            row[col] = None if val is None or val < 0 else float(val) * scale
        if ref is None:
            ref = row
        for col in DROP_COLUMNS:
            both = row[col] is not None and ref[col] is not None
            row[f'{col} drop'] = ref[col] - row[col] if both else None
        rows.append(row)
    columns = [c for c, _, _ in COLUMNS] + [f'{c} drop' for c in DROP_COLUMNS]
    return dict(columns=columns, rows=rows)


def to_markdown(table: dict) -> str:
    """Markdown of :func:`drop_table`'s output (one decimal, '-' when
    missing)."""
    cols = ['condition'] + table['columns']
    lines = ['| ' + ' | '.join(cols) + ' |',
             '|' + '---|' * len(cols)]
    for row in table['rows']:
        cells = [row['condition']] + [
            '-' if row[c] is None else f'{row[c]:.1f}'
            for c in table['columns']
        ]
        lines.append('| ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


def ap_drop(cfg: Config, checkpoint: str, work_dir: str,
            betas: Sequence[float] = (0.02, )) -> dict:
    """Evaluate on clear val and on foggy val for each beta.

    Args:
        cfg (Config): Test config.
        checkpoint (str): Checkpoint file.
        work_dir (str): Output folder of the runs.
        betas (Sequence[float]): Fog densities, 1/m.

    Returns:
        dict: :func:`drop_table` output plus the raw ``metrics``.
    """
    metrics = {'clear': evaluate_condition(cfg, checkpoint, work_dir)}
    for beta in betas:
        metrics[f'foggy beta={beta}'] = evaluate_condition(
            cfg, checkpoint, work_dir, beta)
    table = drop_table(metrics)
    table['metrics'] = {
        c: {k: float(v) for k, v in m.items()} for c, m in metrics.items()
    }
    return table
