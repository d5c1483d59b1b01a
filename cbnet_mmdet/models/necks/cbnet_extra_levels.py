"""Coarser pyramid levels appended to a neck's outputs, without weights."""
from typing import Sequence, Tuple

import torch.nn.functional as F
from mmdet.registry import MODELS
from mmengine.model import BaseModule
from torch import Tensor


@MODELS.register_module()
class CBNetExtraLevels(BaseModule):
    """Pass a pyramid through and append coarser levels to it.

    Each extra level is the previous coarsest level max-pooled with kernel
    1 and stride 2 (FPN's ``add_extra_convs=False`` levels), so a stride-s
    level of size ``H x W`` gives a stride-2s level of
    ``ceil(H / 2) x ceil(W / 2)``. It has no weights: put after a
    pretrained neck (e.g. YOLOX's PAFPN, strides 8/16/32) in a list of
    necks (built as one ``Sequential``), it gives a two-stage head the
    levels it expects while the pretrained neck's outputs stay as they
    were trained.

    Args:
        num_outs (int): Levels out, at least as many as come in; the
            difference are appended.
    """

    def __init__(self, num_outs: int) -> None:
        super().__init__()
        if not isinstance(num_outs, int) or isinstance(num_outs, bool) or \
                num_outs < 1:
            raise ValueError(
                f'num_outs must be a positive int, got {num_outs!r}')
        self.num_outs = num_outs

    def forward(self, inputs: Sequence[Tensor]) -> Tuple[Tensor, ...]:
        """Append the extra levels.

        Args:
            inputs (Sequence[Tensor]): Levels ``Tensor[N, C_i, H_i, W_i]``,
                finest first.

        Returns:
            tuple[Tensor]: The ``num_outs`` levels, finest first; the first
            ``len(inputs)`` are the inputs themselves.
        """
        outs = list(inputs)
        if not outs:
            raise ValueError('CBNetExtraLevels got no levels')
        if len(outs) > self.num_outs:
            raise ValueError(
                f'CBNetExtraLevels: {len(outs)} levels in, more than '
                f'num_outs={self.num_outs}')
        while len(outs) < self.num_outs:
            outs.append(F.max_pool2d(outs[-1], 1, stride=2))
        return tuple(outs)
