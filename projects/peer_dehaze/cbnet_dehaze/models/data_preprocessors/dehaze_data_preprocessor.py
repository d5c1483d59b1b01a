"""Dehaze images in front of any MMDetection detector."""
from typing import List, Optional, Union

import torch
from mmdet.models.data_preprocessors import DetDataPreprocessor
from mmdet.registry import MODELS
from torch import Tensor

from ..dehazers.base_dehazer import to_rgb3
from ..dehazers.dehazer_checkpoint import load_dehazer_checkpoint

#: Pixel value scale of the loaded images (uint8 range).
PIXEL_MAX = 255.0


@MODELS.register_module()
class CBNetDehazeDataPreprocessor(DetDataPreprocessor):
    """``DetDataPreprocessor`` that first runs a dehazer on every image.

    Put it in any MMDetection config in place of the detector's data
    preprocessor; the usual arguments (``mean``, ``std``, ``bgr_to_rgb``,
    ``pad_size_divisor``, ``batch_augments`` ...) keep their meaning::

        model = dict(data_preprocessor=dict(
            type='CBNetDehazeDataPreprocessor',
            dehaze=dict(type='CBNetAttentionDehazer'),
            dehaze_checkpoint='work_dirs/dehazer/iter_2000.pth'))

    Each image (0-255, in the loader's channel order) is scaled to [0, 1],
    put in RGB order, dehazed, and scaled back, *before* the parent's
    conversion, normalisation and padding: the dehazer sees the image at
    its own size (odd sizes are fine) and the padding keeps ``pad_value``.
    Images of one size are dehazed as one batch. 1-channel (grey) images
    become 3-channel; RGBA images are refused with an error.

    Frozen (default), the dehazer runs in eval mode without gradients and
    its parameters do not train; with ``train_dehazer=True`` it is trained
    jointly with the detector (its parameters belong to the model, so the
    detector's optimizer updates them).

    Args:
        dehaze (dict): Config of the dehazer (``CBNetAttentionDehazer``,
            ``CBNetDarkChannelPrior`` ...).
        dehaze_checkpoint (str, optional): Weights for the dehazer alone,
            loaded by :meth:`init_weights` (see
            :func:`load_dehazer_checkpoint`), which MMEngine's Runner calls
            through the detector's ``init_weights`` before training; a
            detector checkpoint loaded with ``load_from`` (or
            ``init_detector``, which does not initialise) overrides them
            where it has them. So the model builds without the file, as
            MMDet's ``init_cfg=dict(type='Pretrained')`` does.
        strict_checkpoint (bool): Refuse a dehazer checkpoint that does
            not fit exactly. Defaults to True.
        train_dehazer (bool): Train the dehazer with the detector.
            Defaults to False (frozen).
        input_order (str): Channel order of the loaded images, ``'bgr'``
            (mmcv's default) or ``'rgb'``; defaults to ``'rgb'`` when
            ``rgb_to_bgr`` is set, else ``'bgr'``.
        **kwargs: :class:`DetDataPreprocessor` arguments.
    """

    def __init__(self,
                 dehaze: dict,
                 dehaze_checkpoint: Optional[str] = None,
                 strict_checkpoint: bool = True,
                 train_dehazer: bool = False,
                 input_order: Optional[str] = None,
                 **kwargs) -> None:
        super().__init__(**kwargs)
        if input_order is None:
            input_order = 'rgb' if kwargs.get('rgb_to_bgr') else 'bgr'
        if input_order not in ('bgr', 'rgb'):
            raise ValueError(f"CBNetDehazeDataPreprocessor: input_order must "
                             f"be 'bgr' or 'rgb', got {input_order!r}")
        self.input_order = input_order
        self.dehazer = MODELS.build(dehaze)
        self.dehaze_checkpoint = dehaze_checkpoint
        self.strict_checkpoint = strict_checkpoint
        self.train_dehazer = train_dehazer
        if not train_dehazer:
            self.dehazer.requires_grad_(False)
            self.dehazer.eval()

    def init_weights(self) -> None:
        """Load ``dehaze_checkpoint`` into the dehazer, if one is set.

        Raises:
            FileNotFoundError: the file does not exist.
            RuntimeError: it does not fit the dehazer (``strict_checkpoint``).
        """
        if self.dehaze_checkpoint:
            load_dehazer_checkpoint(self.dehazer, self.dehaze_checkpoint,
                                    strict=self.strict_checkpoint)

    def train(self, mode: bool = True):
        """Set the training mode; a frozen dehazer stays in eval mode."""
        super().train(mode)
        if not self.train_dehazer:
            self.dehazer.eval()
        return self

    def _dehaze_batch(self, imgs: Tensor) -> Tensor:
        """Tensor[B, C, H, W] 0-255 (C = 1 or 3) -> dehazed [B, 3, H, W]."""
        imgs = to_rgb3(imgs.float() / PIXEL_MAX, type(self).__name__)
        flip = self.input_order == 'bgr'
        if flip:
            imgs = imgs.flip(1)
        with torch.set_grad_enabled(self.train_dehazer
                                    and torch.is_grad_enabled()):
            out = self.dehazer(imgs)
        if flip:
            out = out.flip(1)
        return out * PIXEL_MAX

    def dehaze_inputs(
            self, inputs: Union[Tensor, List[Tensor]]
    ) -> Union[Tensor, List[Tensor]]:
        """Dehaze a batch tensor or a list of differently sized images.

        Args:
            inputs (Tensor[B, C, H, W] | list[Tensor[C, H, W]]): images,
                0-255, in the loader's channel order.

        Returns:
            The same structure, float 0-255, 3 channels, same order.
        """
        if isinstance(inputs, Tensor):
            return self._dehaze_batch(inputs)
        if not inputs:
            return inputs
        if len({tuple(x.shape) for x in inputs}) == 1:
            return list(self._dehaze_batch(torch.stack(inputs)))
        return [self._dehaze_batch(x[None])[0] for x in inputs]

    def forward(self, data: dict, training: bool = False) -> dict:
        """Dehaze, then MMDetection's preprocessing.

        Args:
            data (dict): ``inputs`` (list of Tensor[C, H, W] or a
                Tensor[B, C, H, W], 0-255) and ``data_samples``.
            training (bool): Whether this is a training step.

        Returns:
            dict: as :meth:`DetDataPreprocessor.forward`.
        """
        data = self.cast_data(data)
        data = dict(data, inputs=self.dehaze_inputs(data['inputs']))
        return super().forward(data, training)
