"""Keep a model's batch norms in eval mode while it trains."""
from typing import Optional, Sequence

from mmdet.registry import HOOKS
from mmengine.hooks import Hook
from mmengine.logging import MMLogger
from mmengine.model import is_model_wrapper
from torch.nn.modules.batchnorm import _BatchNorm


@HOOKS.register_module()
class CBNetNormEvalHook(Hook):
    """Put every batch norm of the model (or of some of its parts) in eval
    mode before each training iteration: their running statistics are
    used and never updated; their affine weight and bias still train.

    What a backbone's ``norm_eval=True`` does for its own layers, for a
    whole detector, whose necks and heads (MMDet's ``YOLOXPAFPN``,
    ``YOLOXHead``) have no such option. Needed where the statistics are
    part of the pretrained function: a checkpoint whose batch norms were
    folded into the convolutions (the ONNX YOLOX-Nano of
    ``tools/model_converters/fetch_pretrained.py yolox_nano``: running
    mean 0, variance 1 - eps, so that each batch norm is the identity plus
    the folded bias) collapses when batches of 4 re-estimate them (1.8
    box AP against 22.6 zero-shot, docs/robustness.md), and small batches
    estimate them poorly in any model.

    MMEngine's training loops call ``model.train()`` before every
    iteration (and after each validation); this hook runs after that, in
    ``before_train_iter``, so every forward of training sees the norms in
    eval mode. Validation and testing are in eval mode anyway.

    Args:
        modules (Sequence[str], optional): Dotted names of the submodules
            whose batch norms to hold (``('backbone', 'neck')``); None:
            the whole model.
    """

    priority = 'VERY_HIGH'

    def __init__(self, modules: Optional[Sequence[str]] = None) -> None:
        if modules is not None and (isinstance(modules, str)
                                    or not all(isinstance(m, str)
                                               for m in modules)):
            raise TypeError('CBNetNormEvalHook: modules must be a list of '
                            f'submodule names, got {modules!r}')
        self.modules = None if modules is None else tuple(modules)
        self._norms = None

    def _find(self, runner) -> list:
        model = runner.model.module if is_model_wrapper(runner.model) \
            else runner.model
        roots = [('', model)]
        if self.modules is not None:
            named = dict(model.named_modules())
            missing = [m for m in self.modules if m not in named]
            if missing:
                raise KeyError(
                    f'CBNetNormEvalHook: the model has no submodule '
                    f'{missing}; its top-level parts are '
                    f'{[n for n, _ in model.named_children()]}')
            roots = [(m, named[m]) for m in self.modules]
        norms = {}
        for prefix, root in roots:
            for name, module in root.named_modules(prefix=prefix):
                if isinstance(module, _BatchNorm):
                    norms[name] = module
        return list(norms.values())

    def before_train(self, runner) -> None:
        """Find the batch norms once and say how many are held."""
        self._norms = self._find(runner)
        where = 'the whole model' if self.modules is None else \
            ', '.join(self.modules)
        MMLogger.get_current_instance().info(
            f'CBNetNormEvalHook: {len(self._norms)} batch norms of {where} '
            'kept in eval mode (running statistics fixed, affine trained)')
        if not self._norms:
            MMLogger.get_current_instance().warning(
                f'CBNetNormEvalHook: {where} has no batch norm: the hook '
                'does nothing')

    def before_train_iter(self, runner, batch_idx: int,
                          data_batch=None) -> None:
        """``eval()`` on each held batch norm (the loop's ``train()`` has
        just set them to train mode)."""
        if self._norms is None:
            self._norms = self._find(runner)
        for norm in self._norms:
            norm.eval()
