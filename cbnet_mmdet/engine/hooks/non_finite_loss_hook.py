"""Stop training at the first NaN/Inf loss, saying where it happened."""
import math
from typing import Dict, List, Optional, Sequence

import torch
from mmdet.registry import HOOKS
from mmengine.hooks import Hook
from mmengine.model import is_model_wrapper
from mmengine.runner import Runner

#: Image paths of the offending batch listed in the error message.
MAX_LISTED = 8


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


@HOOKS.register_module()
class CBNetNonFiniteLossHook(Hook):
    """Raise ``FloatingPointError`` on a NaN/Inf loss or parameter.

    After every training iteration the logged losses (the dict that
    ``train_step`` returns) are checked; every ``param_interval``
    iterations the model's floating-point parameters are checked too (a
    finite loss can still give NaN gradients, e.g. a square root at 0).
    The error names the iteration (1-based, as in the log), the epoch and
    batch index, every non-finite loss with its value, and the images of
    the batch, e.g.::

        FloatingPointError: non-finite loss at iteration 17 (epoch 2,
        batch 3): s2.loss_mask=nan, loss=nan; batch images: a.png, b.png

    The hook runs before ``CheckpointHook`` (priority ``ABOVE_NORMAL``), so
    weights corrupted by the offending step are never saved: the last
    checkpoint on disk is clean, and ``tools/train.py --resume`` restarts
    from it. In distributed training the rank that sees the NaN raises and
    the launcher (torchrun) stops the others.

    With ``AmpOptimWrapper`` only the losses and the parameters are
    checked, never the gradients: dynamic loss scaling produces infinite
    gradients on purpose and skips those steps.

    Args:
        param_interval (int): Check the parameters every this many
            iterations; 0 disables the check. Defaults to 50.
    """

    priority = 'ABOVE_NORMAL'

    def __init__(self, param_interval: int = 50) -> None:
        if not isinstance(param_interval, int) or param_interval < 0:
            raise ValueError('CBNetNonFiniteLossHook: param_interval must '
                             f'be an int >= 0, got {param_interval!r}')
        self.param_interval = param_interval

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

    def after_train_iter(self,
                         runner: Runner,
                         batch_idx: int,
                         data_batch: Optional[dict] = None,
                         outputs: Optional[dict] = None) -> None:
        """Check the losses (and the parameters every ``param_interval``).

        Raises:
            FloatingPointError: A loss or a parameter is NaN or infinite.
        """
        bad = non_finite_items(outputs or {})
        if bad:
            listed = ', '.join(f'{k}={v}' for k, v in bad.items())
            raise FloatingPointError(
                f'non-finite loss at {self._where(runner, batch_idx)}: '
                f'{listed}{self._images(data_batch)}. The weights of this '
                f'step were not saved; lower the lr, check the data, or '
                f'resume from the last checkpoint with --resume.')
        if self.param_interval and self.every_n_train_iters(
                runner, self.param_interval):
            names = self.non_finite_parameters(runner.model)
            if names:
                raise FloatingPointError(
                    f'non-finite parameters after '
                    f'{self._where(runner, batch_idx)} (finite losses, so '
                    f'the gradients were not): {", ".join(names[:5])}'
                    f'{" ..." if len(names) > 5 else ""} '
                    f'({len(names)} tensors){self._images(data_batch)}')

    @staticmethod
    @torch.no_grad()
    def non_finite_parameters(model: torch.nn.Module) -> Sequence[str]:
        """Names of the floating-point parameters holding a NaN or Inf.

        One fused reduction over all parameters (``torch._foreach_norm``:
        a tensor's norm is finite iff all its elements are), then names
        only for the offending ones.

        Args:
            model (nn.Module): The (possibly DDP-wrapped) model.

        Returns:
            list[str]: Parameter names, empty when all are finite.
        """
        if is_model_wrapper(model):
            model = model.module
        named = [(n, p) for n, p in model.named_parameters()
                 if p.is_floating_point() and p.numel()]
        if not named:
            return []
        norms = torch.stack(torch._foreach_norm([p for _, p in named]))
        finite = torch.isfinite(norms)
        if bool(finite.all()):
            return []
        # an overflowing norm of finite values is not an error
        return [
            n for (n, p), ok in zip(named, finite.tolist())
            if not ok and not bool(torch.isfinite(p).all())
        ]
