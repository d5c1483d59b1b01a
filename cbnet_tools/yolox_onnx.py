"""The ONNX side of the YOLOX converter (:mod:`cbnet_tools.yolox_weights`):
read an ONNX YOLOX whose batch norms are folded into its convolutions,
check its graph against MMDet's model, convert its weights, and compare
its outputs (onnxruntime, optional) with the converted model's.

Needs the ``onnx`` package (``pip install "cbnet_mmdet[onnx]"``); the
output check also ``onnxruntime``.
"""
import os.path as osp
from collections import OrderedDict
from typing import List, Optional, Sequence

import torch

from .yolox_weights import Row, raw_outputs


def _onnx():
    try:
        import onnx
        from onnx import numpy_helper
    except ImportError:
        raise ImportError(
            'reading an ONNX file needs the onnx package: pip install '
            '"cbnet_mmdet[onnx]" (or onnx==1.17.0)') from None
    return onnx, numpy_helper


def load_onnx(path: str):
    """The ONNX model at ``path``.

    Raises:
        FileNotFoundError: No such file.
        ValueError: The file is not an ONNX model.
    """
    if not osp.isfile(path):
        raise FileNotFoundError(f'{path} not found')
    onnx, _ = _onnx()
    try:
        return onnx.load(path)
    except Exception as err:  # protobuf's DecodeError and friends
        raise ValueError(f'{path} is not an ONNX model: {err}') from err


def onnx_convs(model) -> List[dict]:
    """The ``Conv`` nodes of an ONNX graph in graph order: ``node``,
    ``weight`` and ``bias`` (numpy arrays; bias None when absent) and the
    attributes ``group``, ``strides``, ``pads``, ``kernel_shape``."""
    onnx, numpy_helper = _onnx()
    inits = {i.name: i for i in model.graph.initializer}
    convs = []
    for node in model.graph.node:
        if node.op_type != 'Conv':
            continue
        if node.input[1] not in inits:
            raise ValueError(f'ONNX Conv {node.name}: its weight is not a '
                             'constant of the file')
        attrs = {a.name: onnx.helper.get_attribute_value(a)
                 for a in node.attribute}
        bias = numpy_helper.to_array(inits[node.input[2]]) \
            if len(node.input) > 2 and node.input[2] in inits else None
        convs.append(dict(
            node=node, weight=numpy_helper.to_array(inits[node.input[1]]),
            bias=bias, group=int(attrs.get('group', 1)),
            strides=list(attrs.get('strides', [1, 1])),
            pads=list(attrs.get('pads', [0, 0, 0, 0])),
            kernel_shape=list(attrs.get('kernel_shape', []))))
    return convs


def _activated_consumers(model, tensor: str) -> set:
    """Op types that read ``tensor`` after its activation (SiLU is
    exported as ``Sigmoid`` + ``Mul``; ``Relu``/``LeakyRelu`` likewise
    passed through)."""
    readers = {}
    for node in model.graph.node:
        for name in node.input:
            readers.setdefault(name, []).append(node)
    found, frontier, seen = set(), [tensor], set()
    while frontier:
        name = frontier.pop()
        for node in readers.get(name, []):
            if node.op_type in ('Sigmoid', 'Mul', 'Relu', 'LeakyRelu',
                                'HardSigmoid', 'HardSwish'):
                if node.name not in seen:
                    seen.add(node.name)
                    frontier += list(node.output)
            else:
                found.add(node.op_type)
    return found


def check_graph(model, convs: Sequence[dict], rows: Sequence[Row],
                mmdet_model: torch.nn.Module) -> None:
    """Check that the ONNX convolutions are the table's, one for one.

    Raises:
        ValueError: Another count of convolutions, a weight shape, stride,
            padding or group count that is not MMDet's module's, or a
            ``CSPLayer`` whose branches are in the other order.
    """
    if len(convs) != len(rows):
        raise ValueError(
            f'the ONNX graph has {len(convs)} convolutions, the YOLOX this '
            f'converter maps (YOLOX-Nano) {len(rows)}: another model')
    modules = dict(mmdet_model.named_modules())
    for i, (conv, (yolox, mmdet, kind)) in enumerate(zip(convs, rows)):
        name = mmdet if kind == 'pred' else f'{mmdet}.conv'
        module = modules.get(name)
        if module is None:
            raise ValueError(f'MMDet model has no module {name}')
        want = dict(shape=tuple(module.weight.shape), group=module.groups,
                    strides=list(module.stride),
                    pads=[module.padding[0], module.padding[1]] * 2)
        have = dict(shape=tuple(conv['weight'].shape), group=conv['group'],
                    strides=conv['strides'], pads=conv['pads'])
        if have != want:
            raise ValueError(
                f'ONNX convolution {i} ({conv["node"].name}) is not '
                f'{yolox} -> {name}: it has {have}, MMDet\'s module '
                f'{want}')
        if conv['bias'] is None:  # folded: every convolution has one
            raise ValueError(
                f'ONNX convolution {i} ({conv["node"].name}) has no bias: '
                'not a file with its batch norms folded')
        reads = _activated_consumers(model, conv['node'].output[0])
        expect = {'short_conv': 'Concat', 'main_conv': 'Conv'}.get(
            mmdet.rsplit('.', 1)[-1])
        if expect is not None and expect not in reads:
            raise ValueError(
                f'ONNX convolution {i} ({conv["node"].name}) is mapped to '
                f'{mmdet}, which feeds a {expect}, but it feeds '
                f'{sorted(reads)}: the CSPLayer branches are swapped')


def convert_onnx(model, rows: Sequence[Row], mmdet_model: torch.nn.Module
                 ) -> 'OrderedDict[str, torch.Tensor]':
    """MMDet weights from a folded ONNX YOLOX (:func:`check_graph` first).

    Each folded convolution becomes MMDet's convolution plus a batch norm
    that is the identity plus the folded bias (weight 1, bias ``b``,
    running mean 0, running variance ``1 - eps`` with the model's eps).
    """
    convs = onnx_convs(model)
    check_graph(model, convs, rows, mmdet_model)
    modules = dict(mmdet_model.named_modules())
    out = OrderedDict()
    for conv, (_, mmdet, kind) in zip(convs, rows):
        weight = torch.from_numpy(conv['weight'].copy()).float()
        bias = torch.from_numpy(conv['bias'].copy()).float()
        if kind == 'pred':
            out[f'{mmdet}.weight'], out[f'{mmdet}.bias'] = weight, bias
            continue
        eps = modules[f'{mmdet}.bn'].eps
        out[f'{mmdet}.conv.weight'] = weight
        out[f'{mmdet}.bn.weight'] = torch.ones_like(bias)
        out[f'{mmdet}.bn.bias'] = bias
        out[f'{mmdet}.bn.running_mean'] = torch.zeros_like(bias)
        out[f'{mmdet}.bn.running_var'] = torch.full_like(bias, 1.0 - eps)
        out[f'{mmdet}.bn.num_batches_tracked'] = torch.tensor(0)
    return out


def onnx_output_gap(path: str, model: torch.nn.Module,
                    seed: int = 0) -> Optional[float]:
    """Largest absolute difference between the ONNX file's output (run by
    onnxruntime) and :func:`raw_outputs` of ``model`` on one random input
    of the file's input size; None when onnxruntime is not installed."""
    try:
        import onnxruntime
    except ImportError:
        return None
    session = onnxruntime.InferenceSession(
        path, providers=['CPUExecutionProvider'])
    spec = session.get_inputs()[0]
    shape = [d if isinstance(d, int) and d > 0 else s
             for d, s in zip(spec.shape, (1, 3, 416, 416))]
    images = torch.rand(*shape, generator=torch.Generator().manual_seed(
        seed)) * 255
    want = session.run(None, {spec.name: images.numpy()})[0]
    have = raw_outputs(model, images).numpy()
    if have.shape != want.shape:
        raise ValueError(f'the converted model outputs {have.shape}, the '
                         f'ONNX file {want.shape}')
    return float(abs(have - want).max())
