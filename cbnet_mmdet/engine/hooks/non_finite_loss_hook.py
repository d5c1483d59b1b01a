"""Stop training at the first NaN/Inf loss or blow-up, saying where it
happened and which checkpoint is clean."""
import math
import os.path as osp
import random
import statistics
from collections import deque
from typing import Deque, Dict, List, Optional, Sequence, Tuple

import numpy as np
import torch
from mmdet.registry import HOOKS
from mmengine.hooks import Hook
from mmengine.model import is_model_wrapper
from mmengine.registry import MODELS
from mmengine.runner import Runner

from cbnet_mmdet.utils.checkpoint.files import (DIVERGENCE_RECORD,
                                                intact_checkpoints,
                                                record_divergence)

#: Image paths of the offending batch listed in the error message.
MAX_LISTED = 8
#: Where a checkpoint keeps the check's state.
STATE_KEY = 'non_finite_check'


def non_finite_items(values: Dict[str, object]) -> Dict[str, float]:
    """The entries of a log-vars dict whose value is NaN or infinite.

    Args:
        values (dict[str, Tensor | float]): What ``train_step`` returned
            (0-d tensors or numbers, one per logged loss).

    Returns:
        dict[str, float]: Offending names and their values (``nan``,
        ``inf``, ``-inf``; the first non-finite element for a tensor of
        several elements).
    """
    bad = {}
    for name, value in values.items():
        if isinstance(value, torch.Tensor):
            if value.numel() == 0 or not value.is_floating_point():
                continue
            finite = torch.isfinite(value.detach())
            if not bool(finite.all()):
                bad[name] = float(value.detach()[~finite].flatten()[0])
        elif isinstance(value, float) and not math.isfinite(value):
            bad[name] = value
    return bad


def batch_image_paths(data_batch: Optional[dict]) -> List[str]:
    """``img_path`` (or ``img_id``) of every sample of a data batch."""
    if not isinstance(data_batch, dict):
        return []
    samples = data_batch.get('data_samples') or []
    paths = []
    for sample in samples:
        meta = getattr(sample, 'metainfo', None) or {}
        name = meta.get('img_path', meta.get('img_id'))
        if name is not None:
            paths.append(str(name))
    return paths


def blowup_onset(history: Sequence[Tuple[int, float]],
                 factor: float) -> Optional[int]:
    """First iteration of ``history`` whose value exceeds ``factor`` times
    the (positive) median of the values before it (None: none does).

    Args:
        history (Sequence[tuple[int, float]]): ``(iteration, value)`` in
            order.
        factor (float): The blow-up factor.
    """
    for i in range(1, len(history)):
        base = statistics.median(v for _, v in history[:i])
        if base > 0 and history[i][1] > factor * base:
            return history[i][0]
    return None


class DivergenceError(FloatingPointError):
    """A finite loss, gradient norm or weight norm blew up (a
    ``FloatingPointError``, like the NaN/Inf case)."""


@HOOKS.register_module()
class CBNetNonFiniteLossHook(Hook):
    """Raise ``FloatingPointError`` on a NaN/Inf loss or parameter, or on a
    finite blow-up.

    After every training iteration the logged losses (the dict that
    ``train_step`` returns) are checked; every ``param_interval``
    iterations the model's floating-point parameters are checked too (a
    finite loss can still give NaN gradients, e.g. a square root at 0).
    Finite divergence is caught against running statistics:

    * the total loss (``loss``), and the gradient norm when the optimiser
      wrapper logs one (``clip_grad``: ``train/grad_norm``), above
      ``blowup_factor`` times the median of the last ``window``
      iterations (once ``min_history`` values are known; not while that
      median is <= 0);
    * the parameters' total norm (every ``param_interval``) above
      ``blowup_factor`` times its value when training started.

    A ``DivergenceError`` (a ``FloatingPointError``) is raised then. A
    loss or gradient norm above ``warn_factor`` times the running median
    (a rise the stop does not catch yet, e.g. an lr far too high) is
    logged once per run as a warning.

    A run that starts from weights (``load_from``, not ``--resume``) is
    also judged against a freshly initialised model of its config
    (``start_factor``): at the first iteration the same batch goes
    through a fresh model (built from ``runner.cfg.model``, its
    ``init_weights()``, no gradients, the random state left as it was);
    a first loss above ``start_factor`` times the fresh model's is a
    ``DivergenceError`` naming the checkpoint (the weights are not sound,
    e.g. written after another run diverged), and both losses are logged
    either way. It costs one model build and one forward pass, once. The
    error names the iteration (1-based, as in the log), the epoch and
    batch index, the offending values, the images of the batch and the
    last checkpoint of the work dir that is really clean, e.g.::

        FloatingPointError: non-finite loss at iteration 17 (epoch 2,
        batch 3): s2.loss_mask=nan, loss=nan; batch images: a.png, b.png.
        The weights of this step were not saved; the last clean checkpoint
        is work_dirs/x/epoch_1.pth (iteration 12): resume with --resume
        work_dirs/x/epoch_1.pth. Lower the lr or check the data.

    "Clean" looks back: when the recent losses show a blow-up that began
    at iteration ``s`` (a loss above ``blowup_factor`` times the median
    before it), the weights of iteration ``s - 1`` are already suspect, so
    checkpoints of iteration ``s - 2`` and earlier are clean; for bad
    parameters, those of the last check that found them finite. Later
    checkpoints, written during the blow-up, are named as unsafe, and
    recorded in the work dir's ``diverged.json``
    (:func:`~cbnet_mmdet.utils.checkpoint.files.record_divergence`):
    ``CBNetRunner`` never resumes them (``--resume`` falls back to the
    last clean checkpoint, saying so, or refuses when there is none).

    The check's state (the running histories, the parameters' norm at the
    start, the last iteration they were found finite) is saved in every
    checkpoint (``checkpoint['non_finite_check']``) and restored on
    ``--resume``, so a resumed run is judged against the losses before the
    interruption, not against its own first iterations.

    The hook runs before ``CheckpointHook`` (priority ``ABOVE_NORMAL``), so
    the weights of the offending step are never saved. In distributed
    training the rank that sees the problem raises and the launcher
    (torchrun) stops the others.

    With ``AmpOptimWrapper`` only the losses and the parameters are
    checked for NaN/Inf, never the gradients: dynamic loss scaling
    produces infinite gradients on purpose and skips those steps (an
    infinite logged gradient norm is left out of the running median).

    Args:
        param_interval (int): Check the parameters every this many
            iterations; 0 disables the check. Defaults to 50.
        blowup_factor (float): How many times the running median a loss
            or gradient norm (and the first parameter norm) may reach; 0
            disables the finite checks. Defaults to 100.
        window (int): Iterations of the running median. Defaults to 50.
        min_history (int): Iterations seen before the finite checks start
            (the look-back for the clean checkpoint covers them). Defaults
            to 1: from the second iteration on, a loss 100 x the first is
            caught before the median takes the blow-up in.
        warn_factor (float): A loss or gradient norm above this many
            times the running median is logged as a warning (once per run
            and value); 0 disables it. Defaults to 10.
        start_factor (float): After ``load_from``, how many times a fresh
            model's loss the first loss may reach; 0 disables the check.
            Defaults to 100.
    """

    priority = 'ABOVE_NORMAL'

    def __init__(self,
                 param_interval: int = 50,
                 blowup_factor: float = 100.,
                 window: int = 50,
                 min_history: int = 1,
                 warn_factor: float = 10.,
                 start_factor: float = 100.) -> None:
        if not isinstance(param_interval, int) or param_interval < 0:
            raise ValueError('CBNetNonFiniteLossHook: param_interval must '
                             f'be an int >= 0, got {param_interval!r}')
        if not isinstance(blowup_factor, (int, float)) or not (
                blowup_factor == 0 or blowup_factor > 1):
            raise ValueError('CBNetNonFiniteLossHook: blowup_factor must '
                             f'be 0 (off) or > 1, got {blowup_factor!r}')
        for name, value in (('warn_factor', warn_factor),
                            ('start_factor', start_factor)):
            if not isinstance(value, (int, float)) or not (value == 0
                                                           or value > 1):
                raise ValueError(f'CBNetNonFiniteLossHook: {name} must be '
                                 f'0 (off) or > 1, got {value!r}')
        for name, value in (('window', window), ('min_history',
                                                 min_history)):
            if not isinstance(value, int) or value < 1:
                raise ValueError(f'CBNetNonFiniteLossHook: {name} must be '
                                 f'an int >= 1, got {value!r}')
        self.param_interval = param_interval
        self.blowup_factor = float(blowup_factor)
        self.window = window
        self.min_history = min_history
        self.warn_factor = float(warn_factor)
        self.start_factor = float(start_factor)
        self.warned: set = set()  # keys whose rise was logged
        self._start_from: Optional[str] = None  # load_from to judge
        self.history: Dict[str, Deque[Tuple[int, float]]] = {}
        self.first_param_norm: Optional[float] = None
        self.last_params_ok = 0  # iterations done when last found finite
        self.grad_norms_seen = 0  # length of the logged grad-norm history
        self._loaded: Optional[dict] = None  # state of a loaded checkpoint
        self.unsafe_checkpoints: List[str] = []  # of the last stop

    def state_dict(self) -> dict:
        """The check's state, as saved in checkpoints."""
        return dict(
            history={k: [list(x) for x in h]
                     for k, h in self.history.items()},
            first_param_norm=self.first_param_norm,
            last_params_ok=self.last_params_ok,
            grad_norms_seen=self.grad_norms_seen)

    def before_save_checkpoint(self, runner: Runner,
                               checkpoint: dict) -> None:
        """Save the check's state into the checkpoint."""
        checkpoint[STATE_KEY] = self.state_dict()

    def after_load_checkpoint(self, runner: Runner, checkpoint: dict) -> None:
        """Keep the checkpoint's state; :meth:`before_train` restores it
        when the run resumes (``load_from`` starts a new history)."""
        self._loaded = checkpoint.get(STATE_KEY)

    def before_train(self, runner: Runner) -> None:
        """On resume, restore the state the checkpoint saved; otherwise
        take the parameters' norm now (after ``load_from``) as the
        reference of the blow-up check."""
        if runner.iter > 0 and self._loaded is not None:
            state = self._loaded
            self.history = {
                k: deque(((int(it), float(v)) for it, v in h),
                         maxlen=self.window)
                for k, h in state['history'].items()
            }
            self.first_param_norm = state['first_param_norm']
            self.last_params_ok = int(state['last_params_ok'])
            self.grad_norms_seen = int(state['grad_norms_seen'])
            runner.logger.info(
                f'CBNetNonFiniteLossHook: resumed at iteration '
                f'{runner.iter} with the check\'s history '
                f'({len(self.history.get("loss", ()))} losses)')
        elif runner.iter > 0:
            runner.logger.warning(
                'CBNetNonFiniteLossHook: the checkpoint resumed from holds '
                'no state of this check (written without it): divergence '
                'is judged from this run\'s first iterations')
        self._loaded = None
        load_from = getattr(runner, '_load_from', None)
        self._start_from = (load_from if self.start_factor
                            and runner.iter == 0
                            and isinstance(load_from, str) else None)
        if self.first_param_norm is None:
            norm = self.parameter_check(runner.model)[1]
            if math.isfinite(norm):
                self.first_param_norm = norm

    @staticmethod
    def _where(runner: Runner, batch_idx: int) -> str:
        return (f'iteration {runner.iter + 1} (epoch {runner.epoch + 1}, '
                f'batch {batch_idx})')

    @staticmethod
    def _images(data_batch: Optional[dict]) -> str:
        paths = batch_image_paths(data_batch)
        if not paths:
            return ''
        listed = ', '.join(paths[:MAX_LISTED])
        more = len(paths) - MAX_LISTED
        return f'; batch images: {listed}' + (f' (+{more})' if more > 0
                                              else '')

    def _onset(self, params_bad: bool = False) -> int:
        """First suspect iteration (1-based) given the recent history."""
        onsets = [
            blowup_onset(list(h), self.blowup_factor or math.inf)
            for h in self.history.values()
        ]
        onsets = [o for o in onsets if o is not None]
        if params_bad:
            onsets.append(self.last_params_ok + 2)
        return min(onsets, default=math.inf)

    def clean_checkpoint(self, runner: Runner, now: int,
                         params_bad: bool = False) -> str:
        """The sentence naming the last clean checkpoint of the work dir.

        Args:
            runner (Runner): Its ``work_dir`` is searched.
            now (int): The failing iteration (1-based).
            params_bad (bool): The parameters, not a loss, failed.
        """
        onset = min(self._onset(params_bad), now)
        clean_upto = onset - 2  # weights of iteration onset-1 are suspect
        work_dir = getattr(runner, 'work_dir', None)
        found = intact_checkpoints(work_dir) if isinstance(work_dir,
                                                           str) else []
        clean = [(p, it) for p, it in found if it <= clean_upto]
        unsafe = [p for p, it in found if it > clean_upto]
        self.unsafe_checkpoints = unsafe
        began = (f'the blow-up began at iteration {onset}; '
                 if onset < now else '')
        text = f' The weights of this step were not saved; {began}'
        if clean:
            text += (f'the last clean checkpoint is {clean[0][0]} '
                     f'(iteration {clean[0][1]}): resume with --resume '
                     f'{clean[0][0]}')
        else:
            text += ('no checkpoint of the work dir is clean: start again')
        if unsafe:
            text += (f'; {", ".join(unsafe)} were written after the weights '
                     f'went bad: --resume never takes them '
                     f'({DIVERGENCE_RECORD} in the work dir says so)')
        return text + '. Lower the lr or check the data.'

    def _stop(self, runner: Runner, error: type, head: str, it: int,
              params_bad: bool = False) -> FloatingPointError:
        """The error to raise (``head`` and the clean checkpoint); records
        the unsafe checkpoints in the work dir."""
        self.unsafe_checkpoints = []
        message = head + self.clean_checkpoint(runner, it, params_bad)
        work_dir = getattr(runner, 'work_dir', None)
        if isinstance(work_dir, str) and osp.isdir(work_dir):
            record_divergence(work_dir, message, self.unsafe_checkpoints)
        return error(message)

    def _record(self, key: str, it: int, value: float, runner: Runner,
                batch_idx: int, data_batch: Optional[dict]) -> None:
        """Add a value to its history; raise when it blew up."""
        history = self.history.setdefault(key, deque(maxlen=self.window))
        checked = self.blowup_factor or self.warn_factor
        if checked and len(history) >= self.min_history:
            median = statistics.median(v for _, v in history)
            seen = len(history)
            if median > 0 and self.blowup_factor and \
                    value > self.blowup_factor * median:
                history.append((it, value))
                raise self._stop(
                    runner, DivergenceError,
                    f'{key} blew up at {self._where(runner, batch_idx)}: '
                    f'{value:.4g} is more than {self.blowup_factor:g} x the '
                    f'median {median:.4g} of the last {seen} iterations'
                    f'{self._images(data_batch)}.', it)
            # below the stop (or with it off): a steep rise is a warning
            if median > 0 and self.warn_factor and key not in self.warned \
                    and value > self.warn_factor * median:
                self.warned.add(key)
                stops = (f'training stops at {self.blowup_factor:g} x'
                         if self.blowup_factor else 'the stop is off')
                runner.logger.warning(
                    f'CBNetNonFiniteLossHook: {key} rose to {value:.4g} at '
                    f'{self._where(runner, batch_idx)}, '
                    f'{value / median:.3g} x the median {median:.4g} of the '
                    f'last {seen} iterations; {stops}. Lower the lr if it '
                    f'keeps rising (logged once per run).')
        history.append((it, value))

    def after_train_iter(self,
                         runner: Runner,
                         batch_idx: int,
                         data_batch: Optional[dict] = None,
                         outputs: Optional[dict] = None) -> None:
        """Check the losses (and the parameters every ``param_interval``).

        Raises:
            FloatingPointError: A loss or a parameter is NaN or infinite,
                or (``DivergenceError``) a loss, gradient norm or the
                parameters' norm blew up.
        """
        it = runner.iter + 1
        outputs = outputs or {}
        bad = non_finite_items(outputs)
        if bad:
            listed = ', '.join(f'{k}={v}' for k, v in bad.items())
            raise self._stop(
                runner, FloatingPointError,
                f'non-finite loss at {self._where(runner, batch_idx)}: '
                f'{listed}{self._images(data_batch)}.', it)
        values = self._running_values(runner, outputs)
        if self._start_from is not None:
            load_from, self._start_from = self._start_from, None
            first = dict(values).get('loss')
            if first is not None:
                self._check_start(runner, load_from, first, data_batch)
        for key, value in values:
            self._record(key, it, value, runner, batch_idx, data_batch)
        if self.param_interval and self.every_n_train_iters(
                runner, self.param_interval):
            self._check_parameters(runner, it, batch_idx, data_batch)

    @staticmethod
    def fresh_loss(runner: Runner, data_batch: Optional[dict]) -> float:
        """The total loss of a freshly initialised model of the runner's
        config on ``data_batch`` (no gradients; the random state of
        ``random``, NumPy and torch, CUDA included, is left as it was).

        Raises:
            ValueError: the runner has no model config (it was given a
                model object).
        """
        cfg = getattr(runner, 'cfg', None)
        model_cfg = cfg.get('model') if cfg is not None else None
        if not isinstance(model_cfg, dict):
            raise ValueError('the runner was built from a model object, '
                             'not a config')
        model = runner.model.module if is_model_wrapper(
            runner.model) else runner.model
        device = next(model.parameters()).device
        py_state, np_state = random.getstate(), np.random.get_state()
        cuda = ([torch.cuda.current_device()] if device.type == 'cuda'
                else [])
        try:
            with torch.random.fork_rng(devices=cuda):
                fresh = MODELS.build(model_cfg)
                fresh.init_weights()
                fresh.to(device).train()
                with torch.no_grad():
                    data = fresh.data_preprocessor(data_batch, True)
                    losses = fresh._run_forward(data, mode='loss')
                    loss = fresh.parse_losses(losses)[0]
        finally:
            random.setstate(py_state)
            np.random.set_state(np_state)
        return float(loss)

    def _check_start(self, runner: Runner, load_from: str, first: float,
                     data_batch: Optional[dict]) -> None:
        """Judge the first loss after ``load_from`` against a fresh
        model's (see the class docstring)."""
        try:
            fresh = self.fresh_loss(runner, data_batch)
        except Exception as err:  # the check must not stop a sound run
            runner.logger.warning(
                f'CBNetNonFiniteLossHook: the start from {load_from} was '
                f'not compared with a fresh model ({type(err).__name__}: '
                f'{err})')
            return
        runner.logger.info(
            f'CBNetNonFiniteLossHook: first loss {first:.4g} from the '
            f'weights of {load_from}; a fresh model of this config: '
            f'{fresh:.4g} on the same batch')
        if math.isfinite(fresh) and fresh > 0 and \
                first > self.start_factor * fresh:
            raise DivergenceError(
                f'the first loss {first:.4g} is more than '
                f'{self.start_factor:g} x the loss {fresh:.4g} of a freshly '
                f'initialised model of this config on the same batch: the '
                f'weights of load_from {load_from} are not sound (written '
                f'after a run diverged?). The weights of this step were not '
                f'saved. Start from another checkpoint or from scratch '
                f'(CBNetNonFiniteLossHook(start_factor=0) trains from them '
                f'anyway).')

    def _running_values(self, runner: Runner,
                        outputs: dict) -> List[Tuple[str, float]]:
        """The total loss and this iteration's gradient norm, if logged."""
        values = []
        loss = outputs.get('loss')
        if isinstance(loss, torch.Tensor) and loss.numel() == 1:
            values.append(('loss', float(loss.detach())))
        elif isinstance(loss, float):
            values.append(('loss', loss))
        hub = getattr(runner, 'message_hub', None)
        scalars = getattr(hub, 'log_scalars', None)
        if isinstance(scalars, dict) and 'train/grad_norm' in scalars:
            buffer = scalars['train/grad_norm']
            logged = len(buffer.data[0])
            norm = float(buffer.current())
            # an infinite norm is AMP's loss scaling at work: step skipped
            if logged != self.grad_norms_seen and math.isfinite(norm):
                values.append(('grad_norm', norm))
            self.grad_norms_seen = logged
        return values

    def _check_parameters(self, runner: Runner, it: int, batch_idx: int,
                          data_batch: Optional[dict]) -> None:
        names, norm = self.parameter_check(runner.model)
        if names:
            raise self._stop(
                runner, FloatingPointError,
                f'non-finite parameters after '
                f'{self._where(runner, batch_idx)} (finite losses, so '
                f'the gradients were not): {", ".join(names[:5])}'
                f'{" ..." if len(names) > 5 else ""} '
                f'({len(names)} tensors){self._images(data_batch)}.', it,
                params_bad=True)
        if self.first_param_norm is None:
            self.first_param_norm = norm
        elif self.blowup_factor and norm > self.blowup_factor * max(
                self.first_param_norm, 1e-12):
            raise self._stop(
                runner, DivergenceError,
                f'parameter norm blew up after '
                f'{self._where(runner, batch_idx)}: {norm:.4g} is more than '
                f'{self.blowup_factor:g} x its value at the start '
                f'{self.first_param_norm:.4g}{self._images(data_batch)}.',
                it, params_bad=True)
        self.last_params_ok = it

    @classmethod
    def non_finite_parameters(cls, model: torch.nn.Module) -> Sequence[str]:
        """Names of the floating-point parameters holding a NaN or Inf.

        Args:
            model (nn.Module): The (possibly DDP-wrapped) model.

        Returns:
            list[str]: Parameter names, empty when all are finite.
        """
        return cls.parameter_check(model)[0]

    @staticmethod
    @torch.no_grad()
    def parameter_check(
            model: torch.nn.Module) -> Tuple[Sequence[str], float]:
        """Non-finite parameters and the total norm of all of them.

        One fused reduction over all parameters (``torch._foreach_norm``:
        a tensor's norm is finite iff all its elements are), then names
        only for the offending ones.

        Args:
            model (nn.Module): The (possibly DDP-wrapped) model.

        Returns:
            tuple[list[str], float]: Offending parameter names (empty when
            all are finite) and the parameters' total L2 norm (float64;
            ``inf`` when a norm overflows).
        """
        if is_model_wrapper(model):
            model = model.module
        named = [(n, p) for n, p in model.named_parameters()
                 if p.is_floating_point() and p.numel()]
        if not named:
            return [], 0.0
        norms = torch.stack(torch._foreach_norm([p for _, p in named]))
        finite = torch.isfinite(norms)
        total = float(norms.double().norm())
        if bool(finite.all()):
            return [], total
        # an overflowing norm of finite values is not an error
        return [
            n for (n, p), ok in zip(named, finite.tolist())
            if not ok and not bool(torch.isfinite(p).all())
        ], total
