"""The training config of a run: a recipe under a budget and a seed
(:func:`budget_cfg`), the edits it is made of (move the data, resize every
pipeline), and where a killed run resumes from.
"""
import os.path as osp
import re
from dataclasses import dataclass
from typing import Optional, Tuple

from mmengine.config import Config

from cbnet_mmdet.utils.checkpoint.files import last_checkpoint_in

from .reading import read_config


@dataclass
class Budget:
    """What every recipe of a comparison gets.

    Attributes:
        iters (int): Training iterations (0: evaluate the initialised,
            untrained model).
        batch_size (int): Images per iteration.
        lr (float, optional): Base learning rate; None keeps each config's
            (the shipped demo-size recipes all use 1e-3).
        warmup_iters (int): Linear warm-up from 1 % of the lr, then
            polynomial (power 1) decay to 0 at ``iters``.
        num_workers (int): Data-loading workers.
        img_scale (tuple[int, int], optional): ``(w, h)`` given to every
            ``Resize`` of the training and test pipelines (the data
            preset's image size); None keeps each config's. A recipe whose
            input size is part of the model (the edge model) keeps its own
            (``keep_img_scale`` of :func:`budget_cfg`, its set row's).
    """
    iters: int = 120
    batch_size: int = 4
    lr: Optional[float] = None
    warmup_iters: int = 30
    num_workers: int = 1
    img_scale: Optional[Tuple[int, int]] = None


def replace_data_root(cfg: Config, data_root: str) -> None:
    """Point every dataset and evaluator of ``cfg`` at ``data_root``.

    Every ``data_root`` equal to the config's top-level ``data_root`` and
    every ``ann_file`` under it is rewritten, wherever it sits (wrapped or
    paired datasets, evaluator lists).

    Args:
        cfg (Config): Modified in place.
        data_root (str): The new root.

    Raises:
        KeyError: The config has no top-level ``data_root``.
    """
    if 'data_root' not in cfg:
        raise KeyError(
            f'{cfg.filename}: no top-level data_root, so the harness cannot '
            'move its datasets; define data_root as MMDet configs do')
    old = cfg.data_root.rstrip('/') + '/'
    new = data_root.rstrip('/') + '/'

    def walk(node):
        if isinstance(node, dict):
            for key, value in node.items():
                if isinstance(value, str) and key == 'data_root' and \
                        value.rstrip('/') + '/' == old:
                    node[key] = new
                elif isinstance(value, str) and key == 'ann_file' and \
                        value.startswith(old):
                    node[key] = new + value[len(old):]
                else:
                    walk(value)
        elif isinstance(node, (list, tuple)):
            for value in node:
                walk(value)

    walk(cfg._cfg_dict)
    cfg.data_root = new


def set_img_scale(cfg: Config, img_scale: Tuple[int, int]) -> int:
    """Give every ``Resize`` of ``cfg``'s dataloaders ``scale=img_scale``.

    Every pipeline is walked, wherever it sits (wrapped or paired
    datasets), so training and test images are resized alike.

    Args:
        cfg (Config): Modified in place.
        img_scale (tuple[int, int]): ``(w, h)``, as MMDet's ``Resize``.

    Returns:
        int: How many ``Resize`` transforms were changed.

    Raises:
        ValueError: ``cfg`` has no ``Resize`` in its training or test
            pipelines (the scale would silently not apply; a test-only
            config, without ``train_dataloader``, in its test pipeline).
    """
    scale = tuple(int(v) for v in img_scale)
    if len(scale) != 2 or min(scale) < 1:
        raise ValueError(f'img_scale must be (w, h) > 0, got {img_scale}')
    found = {'train': 0, 'test': 0}

    def walk(node, part):
        if isinstance(node, dict):
            if node.get('type') == 'Resize' and 'scale' in node:
                node['scale'] = scale
                found[part] += 1
            for value in node.values():
                walk(value, part)
        elif isinstance(node, (list, tuple)):
            for value in node:
                walk(value, part)

    for key in ('train_dataloader', 'val_dataloader', 'test_dataloader'):
        if cfg.get(key) is not None:
            walk(cfg[key], 'train' if key.startswith('train') else 'test')
    if cfg.get('train_dataloader') is None:  # a test-only config
        del found['train']
    missing = [part for part, n in found.items() if n == 0]
    if missing:
        raise ValueError(
            f'{cfg.filename}: no Resize with a scale in its {missing} '
            f'pipeline(s), so img_scale {scale} cannot be applied; resize '
            'with MMDet\'s Resize or leave img_scale unset')
    return sum(found.values())


def budget_cfg(config: str, budget: Budget, seed: int, data_root: str,
               work_dir: str, cfg_options: Optional[dict] = None,
               experiment_name: Optional[str] = None,
               keep_img_scale: bool = False) -> Config:
    """The config of one run: ``config`` under ``budget`` and ``seed``.

    The training loop becomes iteration-based (``budget.iters``), the lr
    schedule a linear warm-up and a poly decay over those iterations, the
    batch ``budget.batch_size``; nothing is validated during training (the
    harness tests the last checkpoint), one checkpoint is kept. A config
    without ``train_dataloader`` (test-only: a pretrained detector scored
    zero-shot) keeps no training settings: its data and image size move.

    Args:
        config (str): Config file.
        budget (Budget): The common budget.
        seed (int): Seed of the run (weights, sampling, augmentation).
        data_root (str): Dataset root in the Cityscapes layout.
        work_dir (str): The run's folder.
        cfg_options (dict, optional): Overrides applied last.
        experiment_name (str, optional): MMEngine's name of the run (its
            log folder's), kept by the run's tests as their prefix.
        keep_img_scale (bool): Keep the config's ``Resize`` sizes (its
            input size is part of the model: the edge model), not
            ``budget.img_scale``.

    Returns:
        Config: The run's config.
    """
    cfg = read_config(config)
    replace_data_root(cfg, data_root)
    iters = max(budget.iters, 1)
    trains = cfg.get('train_dataloader') is not None
    if trains:
        cfg.train_dataloader.batch_size = budget.batch_size
        cfg.train_dataloader.num_workers = budget.num_workers
        cfg.train_dataloader.persistent_workers = budget.num_workers > 0
        cfg.train_cfg = dict(
            type='IterBasedTrainLoop', max_iters=iters,
            val_interval=iters + 1)
    for key in ('val_dataloader', 'val_cfg', 'val_evaluator'):
        cfg[key] = None
    if trains:
        warmup = min(budget.warmup_iters, iters)
        cfg.param_scheduler = [
            dict(type='LinearLR', start_factor=1e-2, by_epoch=False,
                 begin=0, end=max(warmup, 1)),
            dict(type='PolyLR', power=1.0, eta_min=0.0, by_epoch=False,
                 begin=0, end=iters),
        ]
    if trains and budget.lr is not None:
        cfg.optim_wrapper.optimizer.lr = budget.lr
    # a checkpoint every sixth of the run (the last one kept), so that a
    # run killed mid-way (a session's end) resumes from it, not from 0
    cfg.default_hooks.checkpoint = dict(
        type='CheckpointHook', interval=checkpoint_interval(iters),
        by_epoch=False, max_keep_ckpts=1, save_best=None)
    cfg.default_hooks.logger = dict(
        type='LoggerHook', interval=max(1, iters // 10))
    cfg.log_processor = dict(type='LogProcessor', window_size=10,
                             by_epoch=False)
    cfg.randomness = dict(seed=seed)
    cfg.work_dir = work_dir
    cfg.auto_scale_lr = dict(enable=False, base_batch_size=16)
    # a recipe whose input size is part of the model (its set row's
    # keep_img_scale: the edge model of configs/pretrained/) keeps its
    # config's under any preset
    if budget.img_scale is not None and not keep_img_scale:
        set_img_scale(cfg, budget.img_scale)
    if cfg_options:
        cfg.merge_from_dict(cfg_options)
    # a killed run resumes from the file found in its work dir, not from
    # the path MMEngine recorded (which names the original folder of a
    # moved work dir); a run that starts keeps the recipe's own load_from
    # (weights to fine-tune from, MMEngine's meaning), if any, with
    # '{seed}' replaced by the run's seed (each seed fine-tunes the weights
    # of the same seed of an earlier comparison)
    resume = resume_file(work_dir)
    cfg.resume = resume is not None
    if resume is not None:
        cfg.load_from = resume
    else:
        load_from = cfg.get('load_from')
        cfg.load_from = None if load_from is None else str(
            load_from).replace('{seed}', str(seed))
    if experiment_name is not None:
        cfg.experiment_name = experiment_name
    return cfg


def checkpoint_interval(iters: int) -> int:
    """Iterations between the checkpoints of a run: a sixth of it."""
    return max(1, -(-iters // 6))


#: The file name of an iteration checkpoint MMEngine saves (``iter_N.pth``).
ITER_CHECKPOINT = re.compile(r'iter_(\d+)\.pth')


def resume_file(work_dir: str) -> Optional[str]:
    """The checkpoint a killed run of ``work_dir`` resumes from.

    MMEngine writes ``last_checkpoint`` (the path of the newest checkpoint)
    in the work dir; a run whose file names an existing ``iter_N.pth`` in
    the work dir (also when the work dir was moved:
    :func:`last_checkpoint_in`) resumes from it (MMEngine restores the
    weights, the optimizer, the lr schedule and skips the data already
    seen). None: start from 0.
    """
    path, _ = last_checkpoint_in(work_dir)
    if path is None or not osp.isfile(path) or \
            ITER_CHECKPOINT.fullmatch(osp.basename(path)) is None:
        return None
    return path


def checkpoint_iter(path: str) -> int:
    """N of a checkpoint ``.../iter_N.pth``."""
    return int(ITER_CHECKPOINT.fullmatch(osp.basename(path)).group(1))
