"""A component that refuses weights of another model, through any loader.

MMEngine's ``load_state_dict`` (behind ``load_from``, ``init_detector``,
``DetInferencer`` and ``init_cfg=dict(type='Pretrained')``) and
PyTorch's non-strict ``Module.load_state_dict`` skip a tensor whose shape
does not fit with a printed warning, and the model then predicts with
random weights where the checkpoint did not fit. Both hand every module
the tensors offered to it in ``Module._load_from_state_dict``; a
component that calls :func:`refuse_misfit` there refuses a checkpoint that
offers it tensors but not all of its own with their shapes, whoever
loads it. A checkpoint that offers it nothing (a checkpoint of a part of
the model) loads as before. :class:`RefuseMisfitMixin` does that call
for a component; PyTorch's and MMEngine's loaders offer a
module only the keys under its own prefix, so a component cannot tell
such a checkpoint from one of another model whose names share nothing
with its own (a CBNet-DD checkpoint, everything under ``student.`` and
``teacher.``: MMEngine warns that every tensor is missing; the project's
tools refuse it, :mod:`cbnet_mmdet.utils.checkpoint.fit`).
"""
from typing import Dict, Sequence

from torch import nn

from ...utils.checkpoint.fit import (CONFIG_HINT, CheckpointMismatchError,
                                     compare_state_dicts, listed)


def refuse_misfit(module: nn.Module,
                  state_dict: Dict,
                  prefix: str,
                  optional: Sequence[str] = ()) -> None:
    """Refuse ``state_dict`` if it offers ``module`` a part of its tensors.

    Args:
        module (nn.Module): The component, inside its own
            ``_load_from_state_dict``.
        state_dict (dict[str, Tensor]): What the loader offers (the whole
            model's state dict; the component's own keys start with
            ``prefix``).
        prefix (str): The component's place in the model
            (``'backbone.'``), as the loader passes it.
        optional (Sequence[str]): Name endings of tensors a checkpoint may
            lack (e.g. a table the published weights do not have); they
            keep their initialisation.

    Raises:
        CheckpointMismatchError: some of the component's tensors are
            offered, but one is missing or has another shape.
    """
    name = type(module).__name__
    where = f' at `{prefix[:-1]}`' if prefix else ''
    offered = {
        k[len(prefix):]: v
        for k, v in state_dict.items() if k.startswith(prefix)
    }
    if not offered:
        return
    own = module.state_dict()
    report = compare_state_dicts(own, offered)
    missing = [k for k in report['missing'] if not k.endswith(tuple(optional))]
    if not missing and not report['mismatched']:
        return
    lines = [
        f'the checkpoint does not fit {name}{where}: it offers '
        f'{len(offered)} tensors for it, {len(report["loaded"])} of the '
        f'{len(own)} it needs fit'
    ]
    if report['mismatched']:
        lines.append(f'  other shape ({len(report["mismatched"])}): '
                     f'{listed(report["mismatched"])}')
    if missing:
        lines.append(f'  missing ({len(missing)}): {listed(missing)}')
    if report['unexpected']:
        lines.append(f'  not {name} tensors ({len(report["unexpected"])}): '
                     f'{listed(report["unexpected"])}')
    lines.append(f'What to do: it is a checkpoint of another model or '
                 f'architecture; {CONFIG_HINT}.')
    raise CheckpointMismatchError('\n'.join(lines))


class RefuseMisfitMixin:
    """``_load_from_state_dict`` that calls :func:`refuse_misfit` first.

    Put it before the ``nn.Module`` base of a component; name the tensors
    a checkpoint may lack in ``misfit_optional`` (name endings).
    """

    #: Name endings of tensors a checkpoint may lack.
    misfit_optional: Sequence[str] = ()

    def _load_from_state_dict(self, state_dict, prefix, local_metadata,
                              strict, missing_keys, unexpected_keys,
                              error_msgs) -> None:
        """PyTorch's loading, after refusing a checkpoint that offers the
        component some of its tensors but not all of them with their
        shapes (:func:`refuse_misfit`), whoever loads it."""
        refuse_misfit(self, state_dict, prefix,
                      optional=self.misfit_optional)
        super()._load_from_state_dict(state_dict, prefix, local_metadata,
                                      strict, missing_keys, unexpected_keys,
                                      error_msgs)
