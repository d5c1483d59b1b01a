"""The test configs of a checkpoint: clear or foggy val, real fog, a
second test set, corrupted images, each a test-only runner's
config (:func:`test_cfg`), composed per measurement by
:func:`ap_drop_cfgs` (the AP drop) and :func:`robustness_cfgs` (the
corruption benchmark).

Real data. Real photographs (DAWN's fog, COCO street's: the data folders
of the presets file's ``test_conditions``, which names their condition)
have no clear twin and no fog density: a config's test set is then
evaluated as it is, under the condition's name (``condition`` of
:func:`ap_drop_cfgs`), and foggy betas are an error. :func:`real_fog_cfg`
turns any detector config of the project into one: its model and test
pipeline on the val split of a VOC real-fog folder, boxes only
(:data:`REAL_FOG`).

Transfer. Given a second test set, ``dict(condition=NAME,
data_root=VOC_FOLDER, ...)`` (a set file's ``transfer_test``: the
fog_transfer set, trained on clear photos), a config is tested on its own
test set first, then on that real-fog folder under ``NAME``
(:func:`transfer_cfg`), so the drop from one to the other is reported.
"""
import copy
import os.path as osp
import re
from typing import Dict, List, Optional, Sequence

from mmengine.config import Config

from cbnet_mmdet.utils.checkpoint.fit import require_checkpoint_fit
from cbnet_tools.quick_eval import check_subset_scoring

CLEAR_TYPES = ('CityscapesDataset', 'CBNetCityscapesDataset')
FOGGY_TYPE = 'CBNetFoggyCityscapesDataset'
#: The dataset of a VOC real-fog folder (:func:`real_fog_cfg`).
VOC_TYPE = 'CBNetVOCFogDataset'
#: ``PackDetInputs``' default ``meta_keys`` (MMDet 3.x).
PACK_META_KEYS = ('img_id', 'img_path', 'ori_shape', 'img_shape',
                  'scale_factor', 'flip', 'flip_direction')
#: Loaders after which ``Corrupt`` is inserted: MMCV's (as a config may
#: name it) and the project's checking one.
LOADER_TYPES = ('LoadImageFromFile', 'mmcv.LoadImageFromFile',
                'mmdet.LoadImageFromFile', 'CBNetLoadImageFromFile')
#: The condition a :func:`real_fog_cfg` test set is reported under.
REAL_FOG = 'real fog'
#: Keys a test-only runner does not build.
TRAINING_KEYS = ('train_dataloader', 'train_cfg', 'optim_wrapper',
                 'param_scheduler', 'val_dataloader', 'val_cfg',
                 'val_evaluator')


def default_betas(condition: Optional[str],
                  betas: Sequence[float] = (0.02, )) -> List[float]:
    """``betas`` for Cityscapes-layout data (``condition`` None), none for
    real data (the name of its condition)."""
    return [] if condition else list(betas)


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
        # real data has no clear / foggy twin: its folder names its
        # condition, or --real-fog tests any config on a VOC folder
        hint = '' if ds.type != VOC_TYPE else (
            f'; a VOC real-fog folder ({cfg.get("data_root")!r}) is tested '
            'as it is when its folder name is a key of test_conditions in '
            'configs/experiments/_base_/presets.py, or with --real-fog '
            'FOLDER')
        raise ValueError(
            f'test_dataloader.dataset.type must be one of '
            f'{CLEAR_TYPES + (FOGGY_TYPE, )}, got {ds.type!r}{hint}')
    if beta is None:
        if ds.type == FOGGY_TYPE:
            ds.type = 'CBNetCityscapesDataset'
            ds.pop('beta', None)
    else:
        ds.type = FOGGY_TYPE
        ds.beta = beta
    return cfg


def real_fog_cfg(cfg: Config, data_root: str, split: Optional[str] = 'val',
                 **dataset_kwargs) -> Config:
    """Copy of ``cfg`` that tests its model on a VOC real-fog folder.

    The test set becomes a :class:`CBNetVOCFogDataset` (``split`` of its
    seeded split, or ``ann_file`` in ``dataset_kwargs``) read with the
    config's own test pipeline, with masks no longer loaded and the ground
    truth passed on for ``CocoMetric`` (``'instances'`` in
    ``PackDetInputs``' ``meta_keys``); the evaluator becomes box AP
    (``CocoMetric``, ``metric='bbox'``: a mask head's masks are ignored).
    It is reported under :data:`REAL_FOG`.

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
    dataset = dict(type=VOC_TYPE, data_root=data_root,
                   ann_file='', test_mode=True, pipeline=pipeline)
    if split is not None:
        dataset['split'] = split
    dataset.update(dataset_kwargs)
    cfg.test_dataloader.dataset = dataset
    cfg.test_evaluator = [dict(type='CocoMetric', metric='bbox')]
    return cfg


def transfer_cfg(cfg: Config, spec: dict,
                 data_root: Optional[str] = None) -> Config:
    """Copy of ``cfg`` testing its model on a second test set.

    Args:
        cfg (Config): A detector config.
        spec (dict): The second test set (a set file's ``transfer_test``,
            :func:`cbnet_lab.set_conditions.transfer_test`): its
            ``condition``, the VOC folder ``data_root`` and the split's
            :class:`CBNetVOCFogDataset` arguments.
        data_root (str, optional): The VOC folder, in place of
            ``spec['data_root']``.

    Returns:
        Config: :func:`real_fog_cfg` of ``cfg`` on that folder (reported
        under ``spec['condition']``).
    """
    spec = dict(spec)
    name, root = spec.pop('condition'), spec.pop('data_root')
    root = data_root or root
    if not osp.isdir(root):
        raise FileNotFoundError(
            f'the transfer test set {name!r} ({cfg.filename}) is the VOC '
            f'folder {root}, which does not exist; give its folder '
            '(compare_recipes.py --transfer-root DIR)')
    return real_fog_cfg(cfg, root, split=spec.pop('split', 'val'), **spec)


def corrupted_cfg(cfg: Config, corruption: str, severity: int) -> Config:
    """Copy of ``cfg`` whose test images are corrupted.

    Args:
        cfg (Config): Test config; its ``test_dataloader.dataset.pipeline``
            must load images with ``LoadImageFromFile`` (or ours).
        corruption (str): ``imagecorruptions`` name, e.g. ``'fog'``.
        severity (int): 1-5; 0 returns an unchanged copy.

    Returns:
        Config: The copy, ``Corrupt`` right after the loader.

    Raises:
        ValueError: severity outside 0-5, or no loader in the pipeline.
    """
    if severity not in range(6):
        raise ValueError(f'severity must be 0-5, got {severity!r}')
    cfg = copy.deepcopy(cfg)
    if severity == 0:
        return cfg
    pipeline = cfg.test_dataloader.dataset.pipeline
    types = [t.get('type') for t in pipeline]
    at = next((i for i, t in enumerate(types) if t in LOADER_TYPES), None)
    if at is None:
        raise ValueError(
            f'no image loader ({LOADER_TYPES[0]}) in '
            f'test_dataloader.dataset.pipeline: {types}')
    pipeline.insert(
        at + 1,
        dict(type='Corrupt', corruption=corruption, severity=severity))
    return cfg


def test_cfg(cfg: Config, checkpoint: str, work_dir: str, name: str,
             prefix: str = 'test') -> Config:
    """Copy of ``cfg`` for a test-only runner of ``checkpoint``.

    Nothing of training or validation is left to build, a checkpoint of
    another model is refused (the checkpoint-fit check of
    :func:`require_checkpoint_fit`), and a test subset scored against a
    whole annotation file is an error here, before anything runs.

    Args:
        cfg (Config): Test config (model, test dataloader and evaluator).
        checkpoint (str): Checkpoint file.
        work_dir (str): Runner work folder; the logs go to
            ``{work_dir}/{name}``.
        name (str): Name of this run (sub-folder, experiment name).
        prefix (str): Experiment name prefix, where ``cfg`` has no
            ``experiment_name``.

    Returns:
        Config: The copy.
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
    for key in TRAINING_KEYS:
        cfg.pop(key, None)
    return cfg


def _folder(condition: str) -> str:
    """A condition's name as a folder name (``real fog`` -> ``real_fog``)."""
    return re.sub(r'\W+', '_', condition)


def ap_drop_cfgs(cfg: Config, checkpoint: str, work_dir: str,
                 betas: Sequence[float] = (0.02, ),
                 condition: Optional[str] = None,
                 transfer_test: Optional[dict] = None,
                 transfer_root: Optional[str] = None) -> Dict[str, Config]:
    """The test configs of the AP drop, by condition, in order.

    Clear val, then foggy val for each beta; real data (``condition``) is
    tested on the config's own test set only, under that name; with
    ``transfer_test`` the config is then also tested on that set (last
    condition).

    Args:
        cfg (Config): Test config.
        checkpoint (str): Checkpoint file.
        work_dir (str): Output folder of the runs.
        betas (Sequence[float]): Fog densities, 1/m (none for real data).
        condition (str, optional): The name of the config's own test set
            where it is real data (:func:`cbnet_lab.sets.data_condition`);
            None: Cityscapes-layout clear and foggy val.
        transfer_test (dict, optional): A second test set (a set file's
            ``transfer_test``: :func:`transfer_cfg`).
        transfer_root (str, optional): The folder of ``transfer_test``, in
            place of its ``data_root``.

    Returns:
        dict: condition -> :func:`test_cfg` of it.

    Raises:
        ValueError: Foggy betas for real data, or a second test set named
            as a condition of the first.
    """
    if condition and betas:
        raise ValueError(
            f'{cfg.filename}: it tests real data ({condition!r}), which has '
            f'no synthetic-fog twin; give no foggy betas (got {list(betas)})')
    conditions = {condition: cfg} if condition else \
        {'clear': condition_cfg(cfg)}
    folders = {condition: _folder(condition)} if condition else \
        {'clear': 'clear'}
    for beta in betas:
        conditions[f'foggy beta={beta}'] = condition_cfg(cfg, beta)
        folders[f'foggy beta={beta}'] = f'foggy_beta_{beta}'
    if transfer_test is not None:
        name = transfer_test['condition']
        if name in conditions:
            raise ValueError(
                f'the second test set {name!r} is named as a condition of '
                f'the config\'s own test set ({list(conditions)}); give it '
                'another name')
        conditions[name] = transfer_cfg(cfg, transfer_test, transfer_root)
        folders[name] = _folder(name)
    return {condition: test_cfg(c, checkpoint, work_dir, folders[condition],
                                prefix='ap_drop')
            for condition, c in conditions.items()}


def robustness_cfgs(cfg: Config, checkpoint: str, work_dir: str,
                    corruptions: Sequence[str],
                    severities: Sequence[int] = (0, 1, 2, 3, 4, 5),
                    betas: Sequence[float] = ()) -> dict:
    """The test configs of the corruption benchmark and the beta sweep.

    The corruptions are applied to the clear images (of a clear or foggy
    Cityscapes config); the clean images are tested once, for severity 0
    and for the sweep's clear end.

    Args:
        cfg (Config): Test config (clear or foggy Cityscapes dataset).
        checkpoint (str): Checkpoint file.
        work_dir (str): Folder of the runs' logs.
        corruptions (Sequence[str]): Corruption names (groups resolved).
        severities (Sequence[int]): Severities 0-5 (0: clean).
        betas (Sequence[float]): Foggy Cityscapes betas (1/m) to test too.

    Returns:
        dict: ``clean`` (the clean images' :func:`test_cfg`, None when no
        severity 0 and no beta asks for it), ``corrupted`` (``{corruption:
        {severity: test_cfg}}``, None at severity 0: the clean run) and
        ``foggy`` (``{beta: test_cfg}``).
    """
    clear = condition_cfg(cfg, None)

    def runner_cfg(run_cfg: Config, name: str) -> Config:
        return test_cfg(run_cfg, checkpoint, work_dir, name,
                        prefix='robustness')

    corrupted = {
        c: {s: None if s == 0 else runner_cfg(corrupted_cfg(clear, c, s),
                                              f'{c}_{s}')
            for s in severities}
        for c in corruptions}
    clean = runner_cfg(clear, 'clean') if betas or any(
        s == 0 for c in corrupted.values() for s in c) else None
    foggy = {float(b): runner_cfg(condition_cfg(cfg, b), f'foggy_beta_{b}')
             for b in betas}
    return dict(clean=clean, corrupted=corrupted, foggy=foggy)
