"""One run: a recipe trained under a budget and a seed (or not trained:
a test-time variant, a test-only row, a run trained by another set), then
tested on every condition, its record written to ``result.json``
(:mod:`cbnet_lab.run_files`). A killed run resumes from its last
checkpoint when it is run again.
"""
import copy
import json
import os
import os.path as osp
import shutil
import time
from dataclasses import asdict
from typing import Optional, Sequence, Tuple

from cbnet_tools.pretrained import require_pretrained

from .ap_drop import ap_drop
from .config_edits import Budget, ap_drop_cfgs, budget_cfg, checkpoint_iter
from .run_files import (checkpoint_file, read_result, recorded_options,
                        result_file, slug)


def run_recipe(name: str, config: str, seed: int, budget: Budget,
               data_root: str, betas: Sequence[float], out_dir: str,
               cfg_options: Optional[dict] = None,
               weights_of: Optional[str] = None,
               condition: Optional[str] = None,
               transfer_test: Optional[dict] = None,
               transfer_root: Optional[str] = None,
               trained_in: Optional[str] = None,
               test_only: bool = False,
               keep_img_scale: bool = False) -> dict:
    """Train one recipe with one seed and test it on clear and foggy val.

    Finished runs are read back from their ``result.json``. With
    ``weights_of`` nothing is trained: the weights that recipe trained for
    ``seed`` (in ``out_dir``) are tested under this recipe's config.

    Args:
        name (str): Recipe name.
        config (str): Config file.
        seed (int): Seed.
        budget (Budget): Training budget.
        data_root (str): Dataset root.
        betas (Sequence[float]): Fog densities (1/m) to test on.
        out_dir (str): Output folder of the comparison.
        cfg_options (dict, optional): Config overrides.
        weights_of (str, optional): Name of the recipe whose weights to
            test (a test-time variant); None trains this recipe.
        condition (str, optional): The name of the config's own test set
            where that is real data (tested as it is, no ``betas``); None:
            clear val, then foggy val per beta.
        transfer_test (dict, optional): A second test set (its set's
            ``transfer_test``), tested after the first.
        transfer_root (str, optional): The folder of ``transfer_test``
            (None: its own ``data_root``).
        trained_in (str, optional): The ``result.json`` of a finished run
            that trained this recipe as it is
            (:func:`cbnet_lab.run_files.find_trained`): its checkpoint is
            linked here and tested, nothing is trained.
        test_only (bool): Train nothing: test the weights the config loads
            (``load_from``: a pretrained detector, zero-shot).
        keep_img_scale (bool): Keep the config's ``Resize`` sizes, not the
            budget's ``img_scale`` (its input size is part of the model).

    Returns:
        dict: ``recipe``, ``config``, ``seed``, ``train_time_s`` (None for
        a test-time variant, which also has ``weights_of``, and for a
        test-only row, which has ``test_only`` and ``weights``; the source
        run's with ``trained_in``, then also ``trained_in``: that run's
        folder and ``trained_as``: its recipe), ``metrics`` (per
        condition: ``clear``, ``foggy beta=B``, or ``condition``; the
        second test set's).
    """
    from mmengine.runner import Runner

    path = result_file(out_dir, name, seed)
    run_dir = osp.dirname(path)
    if osp.isfile(path):
        return read_result(path, budget, cfg_options)
    stamp = time.strftime('%Y%m%d_%H%M%S')
    cfg = budget_cfg(config, budget, seed, data_root, run_dir, cfg_options,
                     experiment_name=f'{slug(name)}_seed{seed}_{stamp}',
                     keep_img_scale=keep_img_scale)
    extra = {}
    if test_only:
        checkpoint = cfg.get('load_from')
        if not checkpoint:
            raise ValueError(
                f'recipe {name!r} is test-only (it trains nothing), but its '
                f'config {config} loads no weights (load_from)')
        require_pretrained(cfg)  # a known file names its fetch command
        checkpoint = osp.expanduser(checkpoint)
        if not osp.isfile(checkpoint):
            raise FileNotFoundError(
                f'recipe {name!r} tests {checkpoint} (its load_from), which '
                'does not exist')
        weights = checkpoint
        checkpoint, added = with_front_end(cfg, checkpoint, run_dir)
        train_time, extra = None, dict(test_only=True, weights=weights)
        if added:
            extra['front_end_tensors'] = added
    elif weights_of is not None:
        checkpoint = checkpoint_file(out_dir, weights_of, seed, budget)
        if not osp.isfile(checkpoint):
            done = osp.isfile(result_file(out_dir, weights_of, seed))
            why = ('its result.json is there but not its weights (a run '
                   'restored from a record?): train that run again here '
                   '(remove its result.json) or use the work dir that '
                   'holds them') if done else \
                ('that run has not been trained in this work dir: run the '
                 f'comparison with {weights_of!r} (list it before '
                 f'{name!r}) first')
            raise FileNotFoundError(
                f'recipe {name!r} trains nothing: it tests the weights of '
                f'{weights_of!r}, seed {seed}, but {checkpoint} does not '
                f'exist; {why}')
        checkpoint, added = with_front_end(cfg, checkpoint, run_dir)
        train_time, extra = None, dict(weights_of=weights_of)
        if added:  # the source's weights and a front end of its own
            extra['front_end_tensors'] = added
    elif trained_in is not None:
        with open(trained_in) as f:
            source = json.load(f)
        checkpoint = checkpoint_file(out_dir, name, seed, budget)
        if not osp.isfile(checkpoint):
            weights = osp.join(osp.dirname(trained_in),
                               osp.basename(checkpoint))
            os.makedirs(run_dir, exist_ok=True)
            try:  # the same file, not a copy, where the disk allows
                os.link(weights, checkpoint)
            except OSError:
                shutil.copy2(weights, checkpoint)
        train_time = source['train_time_s']
        extra = dict(trained_in=osp.dirname(trained_in),
                     trained_as=source['recipe'])
        extra.update({k: source[k] for k in (
            'resumed_at_iter', 'train_time_extrapolated') if k in source})
    else:
        require_pretrained(cfg)
        resumed = checkpoint_iter(cfg.load_from) \
            if budget.iters > 0 and cfg.resume else None
        runner = Runner.from_cfg(cfg)
        start = time.perf_counter()
        checkpoint = checkpoint_file(out_dir, name, seed, budget)
        if budget.iters > 0:
            runner.train()
        else:
            _save_untrained(runner, checkpoint)
        train_time = time.perf_counter() - start
        del runner
        if resumed is not None:
            # this process trained iterations resumed..iters only: the
            # whole run's time is extrapolated, and the record says so
            done = budget.iters - resumed
            train_time = train_time * budget.iters / done if done else None
            extra = dict(resumed_at_iter=resumed,
                         train_time_extrapolated=True)
    table = ap_drop(ap_drop_cfgs(cfg, checkpoint, osp.join(run_dir, 'test'),
                                 betas, condition=condition,
                                 transfer_test=transfer_test,
                                 transfer_root=transfer_root))
    result = dict(
        recipe=name, config=config, seed=seed, budget=asdict(budget),
        train_time_s=train_time, metrics=table['metrics'], **extra)
    if cfg_options:
        # what else it was trained with (read_result refuses to mix it)
        result['cfg_options'] = recorded_options(cfg_options)
    os.makedirs(run_dir, exist_ok=True)
    with open(path, 'w') as f:
        json.dump(result, f, indent=1)
    return result


def with_front_end(cfg, checkpoint: str, run_dir: str) -> Tuple[str, int]:
    """The weights a test-only row tests: ``checkpoint``, or a copy of it
    with the weights of a front end that the row puts in front of it.

    A test-only row (``weights_of``) may put a part with weights in front
    of another row's detector: a learned dehazer in its data preprocessor,
    whose own ``init_weights`` loads it from its own file
    (``dehaze_checkpoint``). The detector's checkpoint has none of those
    tensors, and ``Runner.test`` does not initialise the model: tested as
    it is, the checkpoint-fit check refuses it (rightly: the front end
    would run with random weights). The data preprocessor alone is built
    and initialised, and its tensors that the checkpoint lacks (under
    ``data_preprocessor.``) are added to a copy in ``run_dir``; every
    other tensor still comes from ``checkpoint`` and is still checked. A
    front end without weights (the dark channel prior) tests
    ``checkpoint`` itself, unread here.

    Args:
        cfg (Config): The test-only row's config.
        checkpoint (str): The other row's checkpoint.
        run_dir (str): The test-only run's folder.

    Returns:
        tuple[str, int]: The checkpoint to test and how many tensors were
        added (0: ``checkpoint`` itself).
    """
    from mmdet.registry import MODELS
    from mmengine.registry import init_default_scope
    from mmengine.runner.checkpoint import save_checkpoint
    from mmengine.utils import import_modules_from_strings

    from cbnet_mmdet.utils.checkpoint.files import read_checkpoint
    if cfg.get('custom_imports'):
        import_modules_from_strings(**cfg.custom_imports)
    init_default_scope(cfg.get('default_scope', 'mmdet'))
    front = MODELS.build(copy.deepcopy(cfg.model.data_preprocessor))
    names = list(front.state_dict())
    if not names:
        return checkpoint, 0
    ckpt = read_checkpoint(checkpoint)
    state = ckpt.get('state_dict', ckpt)
    missing = [k for k in names if f'data_preprocessor.{k}' not in state]
    if not missing:
        return checkpoint, 0
    front.init_weights()
    weights = front.state_dict()
    state = dict(state, **{f'data_preprocessor.{k}': weights[k].cpu()
                           for k in missing})
    meta = dict(ckpt.get('meta') or {}, front_end_added=len(missing))
    out = osp.join(run_dir, 'front_end_' + osp.basename(checkpoint))
    os.makedirs(run_dir, exist_ok=True)
    save_checkpoint(dict(state_dict=state, meta=meta), out)
    return out, len(missing)


def _save_untrained(runner, path: str) -> None:
    """Initialise the runner's model and save it as a checkpoint."""
    import torch
    from mmengine.runner.checkpoint import save_checkpoint, weights_to_cpu
    torch.manual_seed(runner.seed)
    runner.model.init_weights()
    save_checkpoint(
        dict(state_dict=weights_to_cpu(runner.model.state_dict()),
             meta=dict(untrained=True)), path)


def execute(job) -> dict:
    """:func:`run_recipe` of a :class:`cbnet_lab.plan.Job`: the task every
    executor runs (:mod:`cbnet_lab.executors`), here or in a worker
    process."""
    return run_recipe(job.name, job.config, job.seed, job.budget,
                      job.data_root, job.betas, job.out_dir,
                      job.cfg_options, weights_of=job.weights_of,
                      condition=job.condition,
                      transfer_test=job.transfer_test,
                      transfer_root=job.transfer_root,
                      trained_in=job.trained_in, test_only=job.test_only,
                      keep_img_scale=job.keep_img_scale)
