"""Data preprocessor for stacked foggy/clear image pairs."""
from typing import List, Tuple, Union

import torch
from mmdet.models.data_preprocessors import DetDataPreprocessor
from mmdet.registry import MODELS
from mmengine.model import ImgDataPreprocessor
from torch import Tensor

#: Channels of one image; a paired input holds two of them.
IMG_CHANNELS = 3


@MODELS.register_module()
class CBNetPairedDataPreprocessor(DetDataPreprocessor):
    """``DetDataPreprocessor`` that also accepts 6-channel paired images.

    The paired pipeline (``CBNetLoadPairedImageFromFile``) stacks the foggy
    image (channels 0-2) and the clear image of the same scene (channels
    3-5) so that MMDetection's geometric transforms crop, flip and resize
    both identically. MMEngine's ``ImgDataPreprocessor`` only normalises 1-
    or 3-channel images, so this class splits a 6-channel input into its two
    halves, runs the usual BGR->RGB conversion, normalisation (the 3-value
    ``mean``/``std``) and padding on each, and concatenates them again:
    the output is ``Tensor[B, 6, H, W]`` with the normalised foggy image in
    channels 0-2 and the clear one in channels 3-5. 3-channel inputs (e.g. a
    plain foggy or clear validation set) pass through the parent unchanged.

    Args:
        batch_augments: Not supported (must be ``None``): batch augments
            such as ``BatchSyncRandomResize`` would have to be applied to
            both halves identically.
        **kwargs: Forwarded to :class:`DetDataPreprocessor` (``mean``,
            ``std``, ``bgr_to_rgb``, ``pad_size_divisor``, ``pad_mask`` ...).
    """

    def __init__(self, batch_augments=None, **kwargs) -> None:
        if batch_augments:
            raise ValueError(
                'CBNetPairedDataPreprocessor: `batch_augments` is not '
                'supported; use pipeline transforms, which see the stacked '
                'foggy/clear image and transform both halves identically')
        super().__init__(batch_augments=None, **kwargs)

    @staticmethod
    def _split(
        inputs: Union[Tensor, List[Tensor]]
    ) -> Tuple[Union[Tensor, List[Tensor]], Union[Tensor, List[Tensor]]]:
        """Split ``[C=6, H, W]`` images (or ``[B, 6, H, W]``) in halves."""
        if isinstance(inputs, Tensor):
            return inputs[:, :IMG_CHANNELS], inputs[:, IMG_CHANNELS:]
        return ([x[:IMG_CHANNELS] for x in inputs],
                [x[IMG_CHANNELS:] for x in inputs])

    def forward(self, data: dict, training: bool = False) -> dict:
        """Preprocess 3-channel or paired 6-channel images.

        Args:
            data (dict): ``inputs`` (list of Tensor[C, H, W] uint8 images or
                a Tensor[B, C, H, W]) and ``data_samples`` from the
                dataloader; C must be 3 or 6, the same for the whole batch.
            training (bool): Whether this is a training step.

        Returns:
            dict: ``inputs`` Tensor[B, C, H', W'] (float, normalised,
            padded) and ``data_samples`` with ``batch_input_shape`` and
            ``pad_shape`` set.
        """
        inputs = data['inputs']
        channels = {int(x.shape[-3]) for x in inputs}
        if channels == {IMG_CHANNELS}:
            return super().forward(data, training)
        if channels != {2 * IMG_CHANNELS}:
            raise ValueError(
                f'CBNetPairedDataPreprocessor: expected images with 3 '
                f'channels or 6 (foggy + clear), got channels {channels}')
        foggy, clear = self._split(inputs)
        out = super().forward(
            dict(inputs=foggy, data_samples=data.get('data_samples')),
            training)
        # The clear half gets the same conversion, normalisation and
        # padding, without touching the data samples a second time.
        clear = ImgDataPreprocessor.forward(
            self, dict(inputs=clear), training)['inputs']
        out['inputs'] = torch.cat([out['inputs'], clear], dim=1)
        return out
