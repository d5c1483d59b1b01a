"""AP drop from Cityscapes to Foggy Cityscapes (the paper's Table 2).

One checkpoint is tested on the clear val images and on the foggy ones
(per beta) with the same annotations, through MMEngine's ``Runner.test``;
only ``test_dataloader.dataset`` changes between runs. Used by
``tools/analysis_tools/ap_drop.py`` and importable by demos.

Real data. A config that sets ``test_condition = NAME`` (the real-fog
configs under ``configs/realfog/``: ``'real fog'``) tests real foggy
photographs, which have no clear twin and no fog density: its test set is
evaluated as it is, under that name, and foggy betas are an error.
:func:`real_fog_cfg` turns any detector config of the project into one:
its model and test pipeline on the val split of a VOC real-fog folder,
boxes only.

Transfer. A config that also sets ``transfer_test = dict(condition=NAME,
data_root=VOC_FOLDER, ...)`` (the fog_transfer recipes of
``configs/pretrained/fog_transfer/``: trained on clear photos) is tested
on its own test set first, then on that real-fog folder under ``NAME``
(:func:`transfer_cfg`), so the drop from one to the other is reported.
"""
import copy
import os.path as osp
import re
from typing import Dict, List, Optional, Sequence

from mmengine.config import Config
from mmengine.runner import Runner

from cbnet_mmdet.utils.checkpoint.fit import require_checkpoint_fit
from cbnet_tools.markdown import markdown_table
from cbnet_tools.quick_eval import check_subset_scoring

from .metric_keys import columns

CLEAR_TYPES = ('CityscapesDataset', 'CBNetCityscapesDataset')
FOGGY_TYPE = 'CBNetFoggyCityscapesDataset'

#: Table columns: (name, metric key, scale). Metrics from ``CocoMetric``
#: (prefix ``coco``) and ``CBNetInstanceMIoUMetric`` (``cityscapes``),
#: reported in percent like the paper.
COLUMNS = columns('box AP', 'mask AP', 'mask AP50', 'mIoU')
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
        dict[str, float]: The evaluators' metrics; see
        :func:`with_empty_coco_results`.
    """
    cfg = copy.deepcopy(cfg)
    check_subset_scoring(cfg)  # a subset scored against every image
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


#: ``PackDetInputs``' default ``meta_keys`` (MMDet 3.x).
PACK_META_KEYS = ('img_id', 'img_path', 'ori_shape', 'img_shape',
                  'scale_factor', 'flip', 'flip_direction')


def real_fog_cfg(cfg: Config, data_root: str, split: Optional[str] = 'val',
                 **dataset_kwargs) -> Config:
    """Copy of ``cfg`` that tests its model on a VOC real-fog folder.

    The test set becomes a :class:`CBNetVOCFogDataset` (``split`` of its
    seeded split, or ``ann_file`` in ``dataset_kwargs``) read with the
    config's own test pipeline, with masks no longer loaded and the ground
    truth passed on for ``CocoMetric`` (``'instances'`` in
    ``PackDetInputs``' ``meta_keys``); the evaluator becomes box AP
    (``CocoMetric``, ``metric='bbox'``: a mask head's masks are ignored);
    ``test_condition`` is ``'real fog'``; a ``transfer_test`` is dropped.

    Args:
        cfg (Config): A detector config of the project (CBNet, CBNet-DD,
            the baselines, the dehaze pipelines...).
        data_root (str): The VOC folder (``Annotations/``,
            ``JPEGImages/``).
        split (str, optional): ``'train'`` or ``'val'`` of the seeded
            split; None with an ``ann_file`` image-set file.
        **dataset_kwargs: More :class:`CBNetVOCFogDataset` arguments
            (``img_suffix='.png'`` for RTTS, ``ann_file``, ``val_fraction``,
            ``split_seed``, ``name_map``, ``ignore_names``...).

    Returns:
        Config: The modified copy.
    """
    cfg = copy.deepcopy(cfg)
    pipeline = []
    for transform in cfg.test_dataloader.dataset.pipeline:
        transform = copy.deepcopy(transform)
        if transform['type'] == 'LoadAnnotations':
            transform.update(with_bbox=True, with_mask=False, with_seg=False)
        elif transform['type'] == 'PackDetInputs':
            keys = tuple(transform.get('meta_keys', PACK_META_KEYS))
            transform['meta_keys'] = keys + ('instances', ) * (
                'instances' not in keys)
        pipeline.append(transform)
    dataset = dict(type='CBNetVOCFogDataset', data_root=data_root,
                   ann_file='', test_mode=True, pipeline=pipeline)
    if split is not None:
        dataset['split'] = split
    dataset.update(dataset_kwargs)
    cfg.test_dataloader.dataset = dataset
    cfg.test_evaluator = [dict(type='CocoMetric', metric='bbox')]
    cfg.test_condition = 'real fog'
    # it tests real fog itself now: no second test set after it
    cfg.pop('transfer_test', None)
    return cfg


def test_condition(cfg: Config) -> Optional[str]:
    """The ``test_condition`` of a real-data config (None: Cityscapes
    clear / foggy val)."""
    name = cfg.get('test_condition')
    if name is not None and (not isinstance(name, str) or not name.strip()):
        raise ValueError(f'{cfg.filename}: test_condition must be a '
                         f'non-empty name, got {name!r}')
    return name


#: Keys of a config's ``transfer_test``: the condition's name and VOC
#: folder are required, the rest are :class:`CBNetVOCFogDataset`'s split
#: arguments.
TRANSFER_KEYS = ('condition', 'data_root', 'split', 'val_fraction',
                 'split_seed', 'ann_file', 'img_suffix')


def transfer_test(cfg: Config) -> Optional[dict]:
    """The ``transfer_test`` of a config (None when it has none), checked.

    Raises:
        ValueError: It lacks ``condition`` or ``data_root``, has a key
            other than :data:`TRANSFER_KEYS`, or names the condition the
            config's own test set is reported under.
    """
    spec = cfg.get('transfer_test')
    if spec is None:
        return None
    where = f'{cfg.filename}: transfer_test'
    if not isinstance(spec, dict):
        raise ValueError(f'{where} must be a dict, got {spec!r}')
    spec = dict(spec)
    unknown = sorted(set(spec) - set(TRANSFER_KEYS))
    if unknown:
        raise ValueError(f'{where}: unknown keys {unknown}; known: '
                         f'{list(TRANSFER_KEYS)}')
    for key in ('condition', 'data_root'):
        if not isinstance(spec.get(key), str) or not spec[key].strip():
            raise ValueError(f'{where} needs a non-empty {key!r}, got '
                             f'{spec.get(key)!r}')
    if spec['condition'] == (test_condition(cfg) or 'clear'):
        raise ValueError(
            f"{where}: condition {spec['condition']!r} is also the name of "
            'the config\'s own test set; give the transfer set another name')
    return spec


def transfer_cfg(cfg: Config, data_root: Optional[str] = None) -> Config:
    """Copy of ``cfg`` testing its model on its ``transfer_test`` set.

    Args:
        cfg (Config): A config with ``transfer_test``.
        data_root (str, optional): The VOC folder, in place of
            ``transfer_test.data_root``.

    Returns:
        Config: :func:`real_fog_cfg` of ``cfg`` on that folder, its
        ``test_condition`` the transfer condition's name.
    """
    spec = transfer_test(cfg)
    if spec is None:
        raise ValueError(f'{cfg.filename} has no transfer_test')
    name, root = spec.pop('condition'), spec.pop('data_root')
    root = data_root or root
    if not osp.isdir(root):
        raise FileNotFoundError(
            f'the transfer test set {name!r} ({cfg.filename}) is the VOC '
            f'folder {root}, which does not exist; give its folder '
            '(compare_recipes.py --transfer-root DIR, or --cfg-options '
            'transfer_test.data_root=DIR)')
    out = real_fog_cfg(cfg, root, split=spec.pop('split', 'val'), **spec)
    out.test_condition = name
    return out


def default_betas(cfg: Config,
                  betas: Sequence[float] = (0.02, )) -> List[float]:
    """``betas`` for a Cityscapes config, none for a real-data one."""
    return [] if test_condition(cfg) else list(betas)


def ap_drop(cfg: Config, checkpoint: str, work_dir: str,
            betas: Sequence[float] = (0.02, ),
            transfer_root: Optional[str] = None) -> dict:
    """Evaluate on clear val and on foggy val for each beta.

    A config with ``test_condition = NAME`` (real data) is tested on its
    own test set only, as condition ``NAME``. A config with
    ``transfer_test`` is then also tested on that set (last condition).

    Args:
        cfg (Config): Test config.
        checkpoint (str): Checkpoint file.
        work_dir (str): Output folder of the runs.
        betas (Sequence[float]): Fog densities, 1/m (none for a config with
            ``test_condition``).
        transfer_root (str, optional): The folder of the config's
            ``transfer_test`` set, in place of its ``data_root``.

    Returns:
        dict: :func:`drop_table` output plus the raw ``metrics``.
    """
    real = test_condition(cfg)
    if real and betas:
        raise ValueError(
            f'{cfg.filename}: test_condition={real!r} tests real data, '
            'which has no synthetic-fog twin; give no foggy betas '
            f'(got {list(betas)})')
    if real:
        metrics = {
            real: evaluate_checkpoint(cfg, checkpoint, work_dir,
                                      re.sub(r'\W+', '_', real),
                                      prefix='ap_drop')
        }
    else:
        metrics = {'clear': evaluate_condition(cfg, checkpoint, work_dir)}
    for beta in betas:
        metrics[f'foggy beta={beta}'] = evaluate_condition(
            cfg, checkpoint, work_dir, beta)
    if transfer_test(cfg) is not None:
        other = transfer_cfg(cfg, transfer_root)
        metrics[other.test_condition] = evaluate_checkpoint(
            other, checkpoint, work_dir,
            re.sub(r'\W+', '_', other.test_condition), prefix='ap_drop')
    table = drop_table(metrics)
    table['metrics'] = {
        c: {k: float(v) for k, v in m.items()} for c, m in metrics.items()
    }
    return table
