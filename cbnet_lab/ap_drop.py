"""AP drop from Cityscapes to Foggy Cityscapes (the paper's Table 2).

One checkpoint is tested under each condition of its test configs
(:func:`cbnet_lab.config_edits.ap_drop_cfgs`: clear val and foggy val per
beta with the same annotations, a real-data config's own test set, a
config's second test set) through MMEngine's ``Runner.test``, and the
drop from the first condition to each other is tabulated. Used by
``tools/analysis_tools/ap_drop.py`` and the comparison harness, and
importable by demos.
"""
from typing import Dict, List

from mmengine.config import Config
from mmengine.runner import Runner

from cbnet_tools.markdown import markdown_table

from .metric_keys import columns

#: Table columns: (name, metric key, scale). Metrics from ``CocoMetric``
#: (prefix ``coco``) and ``CBNetInstanceMIoUMetric`` (``cityscapes``),
#: reported in percent like the paper.
COLUMNS = columns('box AP', 'mask AP', 'mask AP50', 'mIoU')
#: Columns whose drop (clear minus foggy) is reported.
DROP_COLUMNS = ('box AP', 'mask AP', 'mIoU')


def evaluate(cfg: Config) -> Dict[str, float]:
    """``Runner.test`` of a finished test config
    (:func:`cbnet_lab.config_edits.test_cfg`: its checkpoint, work dir and
    name set).

    Returns:
        dict[str, float]: The evaluators' metrics; see
        :func:`with_empty_coco_results`.
    """
    return with_empty_coco_results(cfg, Runner.from_cfg(cfg).test())


#: COCO AP keys set to 0 when a model detects nothing.
EMPTY_AP_KEYS = ('mAP', 'mAP_50', 'mAP_75')


def with_empty_coco_results(cfg: Config,
                            metrics: Dict[str, float]) -> Dict[str, float]:
    """Add AP 0 where ``CocoMetric`` reported nothing for a detection set.

    MMDet's ``CocoMetric`` returns no metric at all (and logs "The testing
    results of the whole dataset is empty") when the model kept no
    detection on any test image, as a detector trained briefly from
    scratch may. The average precision of no detection is 0: this sets
    ``{prefix}/{bbox|segm}_{mAP, mAP_50, mAP_75}`` to 0.0 for each
    ``CocoMetric`` of ``cfg.test_evaluator`` whose keys are all missing
    (proposal metrics untouched).

    Args:
        cfg (Config): The test config.
        metrics (dict[str, float]): ``Runner.test()``'s metrics.

    Returns:
        dict[str, float]: ``metrics`` with the zeros added.
    """
    metrics = dict(metrics)
    evaluators = cfg.get('test_evaluator') or []
    if isinstance(evaluators, dict):
        evaluators = [evaluators]
    for evaluator in evaluators:
        if evaluator.get('type') != 'CocoMetric':
            continue
        prefix = evaluator.get('prefix') or 'coco'
        kinds = evaluator.get('metric', 'bbox')
        kinds = [kinds] if isinstance(kinds, str) else list(kinds)
        for kind in kinds:
            keys = [f'{prefix}/{kind}_{k}' for k in EMPTY_AP_KEYS]
            if kind in ('bbox', 'segm') and \
                    not any(k in metrics for k in keys):
                metrics.update(dict.fromkeys(keys, 0.0))
    return metrics


def drop_table(metrics: Dict[str, Dict[str, float]]) -> dict:
    """Table 2 rows from the metrics of each condition.

    Args:
        metrics (dict): Metrics per condition name; the first one is the
            reference (clear).

    Returns:
        dict: ``{'columns': [...], 'rows': [{'condition', <column>...,
        '<column> drop'...}]}``, values in percent (None if the metric is
        missing). With a single condition (a real-fog set, nothing to drop
        from) there are no drop columns.
    """
    rows: List[dict] = []
    ref = None
    drops = DROP_COLUMNS if len(metrics) > 1 else ()
    for condition, m in metrics.items():
        row = {'condition': condition}
        for col, key, scale in COLUMNS:
            val = m.get(key)
            row[col] = None if val is None or val < 0 else float(val) * scale
        if ref is None:
            ref = row
        for col in drops:
            both = row[col] is not None and ref[col] is not None
            row[f'{col} drop'] = ref[col] - row[col] if both else None
        rows.append(row)
    columns = [c for c, _, _ in COLUMNS] + [f'{c} drop' for c in drops]
    return dict(columns=columns, rows=rows)


def to_markdown(table: dict) -> str:
    """Markdown of :func:`drop_table`'s output (one decimal, '-' when
    missing)."""
    return '\n'.join(markdown_table(
        ['condition'] + table['columns'],
        [[row['condition']] + ['-' if row[c] is None else f'{row[c]:.1f}'
                               for c in table['columns']]
         for row in table['rows']]))


def ap_drop(cfgs: Dict[str, Config]) -> dict:
    """Test under each condition's finished config, in order.

    Args:
        cfgs (dict): condition -> test config
            (:func:`cbnet_lab.config_edits.ap_drop_cfgs`); the first is the
            reference the drops are taken from.

    Returns:
        dict: :func:`drop_table` output plus the raw ``metrics``.
    """
    metrics = {condition: evaluate(cfg) for condition, cfg in cfgs.items()}
    table = drop_table(metrics)
    table['metrics'] = {
        c: {k: float(v) for k, v in m.items()} for c, m in metrics.items()
    }
    return table
