"""A COCO-pretrained YOLOX as MMDetection's own ``YOLOX``: Megvii's
weights (the official ``.pth`` release asset, or an ONNX export with the
batch norms folded into the convolutions) converted to the keys of
MMDet's ``mmdet::yolox/yolox_nano_8xb8-300e_coco.py`` model.

The map is one table (:func:`conv_table`): every convolution of YOLOX in
the order YOLOX's own ``forward`` runs it (the order of the ONNX graph's
``Conv`` nodes), named as YOLOX's ``state_dict`` and as MMDet's. The two
models are the same network (CSPDarknet, PAFPN, decoupled head), with
three differences of naming and order only:

* MMDet's ``CSPLayer`` names YOLOX's ``conv1`` / ``conv2`` / ``conv3`` /
  ``m`` ``main_conv`` / ``short_conv`` / ``final_conv`` / ``blocks``, and
  runs ``short_conv`` before ``main_conv`` (YOLOX: ``conv1`` first);
* YOLOX's head ``stems`` are MMDet's ``neck.out_convs``;
* YOLOX's ``DWConv`` (``dconv``, ``pconv``) is MMDet's
  ``DepthwiseSeparableConvModule`` (``depthwise_conv``,
  ``pointwise_conv``).

A folded convolution (weight ``W``, bias ``b``) goes into MMDet's
``ConvModule`` (convolution without bias, then batch norm) as ``W`` and a
batch norm that is the identity plus ``b``: weight 1, bias ``b``, running
mean 0, running variance ``1 - eps``. Such a model must keep its batch
norms in eval mode when it is fine-tuned (``CBNetNormEvalHook``): batch
statistics would replace the identity.

The ONNX side is :mod:`cbnet_tools.yolox_onnx`. Its ``check_graph``
checks what the weights alone cannot tell apart: each ONNX convolution's
stride, padding and groups against MMDet's module, and that the
``CSPLayer`` branch mapped to ``short_conv`` feeds the concatenation
while the one mapped to ``main_conv`` feeds the bottlenecks (the two
have equal shapes). Its ``onnx_output_gap`` runs the ONNX file with
onnxruntime (optional) and the converted model on the same input.
"""
import os.path as osp
from collections import OrderedDict
from typing import Dict, List, Optional, Sequence, Tuple

import torch

#: MMDet's YOLOX-Nano: the model of this config (80 COCO classes).
NANO_CONFIG = 'mmdet::yolox/yolox_nano_8xb8-300e_coco.py'
#: YOLOX-Nano's depth and width multipliers and its depthwise convolutions.
NANO_ARCH = dict(deepen_factor=0.33, widen_factor=0.25, depthwise=True)
#: CSPDarknet's stage settings (MMDet's ``arch_settings['P5']``): blocks
#: per stage before the depth multiplier.
STAGE_BLOCKS = (3, 9, 9, 3)
#: The tensors of one batch norm (YOLOX's ``bn``, MMDet's ``bn``).
BN_KEYS = ('weight', 'bias', 'running_mean', 'running_var',
           'num_batches_tracked')

#: One row of :func:`conv_table`: (YOLOX module, MMDet module, kind);
#: kind ``'convbn'``: a convolution without bias and its batch norm
#: (YOLOX's ``BaseConv``, MMDet's ``ConvModule``), ``'pred'``: a plain
#: convolution with bias (the head's predictions).
Row = Tuple[str, str, str]


def _conv(yolox: str, mmdet: str, depthwise: bool) -> List[Row]:
    """A 3x3 convolution: ``DWConv`` / ``DepthwiseSeparableConvModule``
    when ``depthwise``, else one ``BaseConv`` / ``ConvModule``."""
    if depthwise:
        return [(f'{yolox}.dconv', f'{mmdet}.depthwise_conv', 'convbn'),
                (f'{yolox}.pconv', f'{mmdet}.pointwise_conv', 'convbn')]
    return [(yolox, mmdet, 'convbn')]


def _csp(yolox: str, mmdet: str, blocks: int, depthwise: bool) -> List[Row]:
    """A ``CSPLayer`` in YOLOX's order: main, short, the bottlenecks,
    final."""
    rows = [(f'{yolox}.conv1', f'{mmdet}.main_conv', 'convbn'),
            (f'{yolox}.conv2', f'{mmdet}.short_conv', 'convbn')]
    for j in range(blocks):
        rows.append((f'{yolox}.m.{j}.conv1', f'{mmdet}.blocks.{j}.conv1',
                     'convbn'))
        rows += _conv(f'{yolox}.m.{j}.conv2', f'{mmdet}.blocks.{j}.conv2',
                      depthwise)
    rows.append((f'{yolox}.conv3', f'{mmdet}.final_conv', 'convbn'))
    return rows


def conv_table(deepen_factor: float = 0.33, depthwise: bool = True,
               neck_blocks: int = 1, num_levels: int = 3,
               stacked_convs: int = 2) -> List[Row]:
    """Every convolution of a YOLOX in YOLOX's execution order.

    Args:
        deepen_factor (float): The depth multiplier (Nano, Tiny, S: 0.33).
        depthwise (bool): Depthwise-separable 3x3 convolutions (Nano).
        neck_blocks (int): Bottlenecks per PAFPN ``CSPLayer``
            (``round(3 * deepen_factor)`` in YOLOX: 1 for Nano).
        num_levels (int): Pyramid levels of the head (strides 8, 16, 32).
        stacked_convs (int): 3x3 convolutions per head branch.

    Returns:
        list[Row]: (YOLOX module, MMDet module, kind); 113 rows for Nano.
    """
    blocks = [max(round(n * deepen_factor), 1) for n in STAGE_BLOCKS]
    rows = [('backbone.backbone.stem.conv', 'backbone.stem.conv', 'convbn')]
    for i, n in enumerate(blocks, 1):
        dark, stage = f'backbone.backbone.dark{i + 1}', f'backbone.stage{i}'
        rows += _conv(f'{dark}.0', f'{stage}.0', depthwise)
        csp = 1
        if i == len(blocks):  # the last stage: SPP before its CSPLayer
            rows += [(f'{dark}.1.conv1', f'{stage}.1.conv1', 'convbn'),
                     (f'{dark}.1.conv2', f'{stage}.1.conv2', 'convbn')]
            csp = 2
        rows += _csp(f'{dark}.{csp}', f'{stage}.{csp}', n, depthwise)
    # PAFPN, top-down then bottom-up, as YOLOPAFPN.forward runs it
    neck = [('lateral_conv0', 'reduce_layers.0', 'conv1x1'),
            ('C3_p4', 'top_down_blocks.0', 'csp'),
            ('reduce_conv1', 'reduce_layers.1', 'conv1x1'),
            ('C3_p3', 'top_down_blocks.1', 'csp'),
            ('bu_conv2', 'downsamples.0', 'conv3x3'),
            ('C3_n3', 'bottom_up_blocks.0', 'csp'),
            ('bu_conv1', 'downsamples.1', 'conv3x3'),
            ('C3_n4', 'bottom_up_blocks.1', 'csp')]
    for yolox, mmdet, kind in neck:
        yolox, mmdet = f'backbone.{yolox}', f'neck.{mmdet}'
        if kind == 'conv1x1':
            rows.append((yolox, mmdet, 'convbn'))
        elif kind == 'conv3x3':
            rows += _conv(yolox, mmdet, depthwise)
        else:
            rows += _csp(yolox, mmdet, neck_blocks, depthwise)
    # the head, level by level, as YOLOXHead.forward runs it
    head = 'bbox_head'
    for k in range(num_levels):
        rows.append((f'head.stems.{k}', f'neck.out_convs.{k}', 'convbn'))
        for branch, pred in (('cls', ('cls',)), ('reg', ('reg', 'obj'))):
            for j in range(stacked_convs):
                rows += _conv(f'head.{branch}_convs.{k}.{j}',
                              f'{head}.multi_level_{branch}_convs.{k}.{j}',
                              depthwise)
            for p in pred:
                rows.append((f'head.{p}_preds.{k}',
                             f'{head}.multi_level_conv_{p}.{k}', 'pred'))
    return rows


def _pairs(rows: Sequence[Row]) -> List[Tuple[str, str]]:
    """(YOLOX key, MMDet key) of every tensor of ``rows``."""
    pairs = []
    for yolox, mmdet, kind in rows:
        if kind == 'pred':
            pairs += [(f'{yolox}.{t}', f'{mmdet}.{t}')
                      for t in ('weight', 'bias')]
        else:
            pairs.append((f'{yolox}.conv.weight', f'{mmdet}.conv.weight'))
            pairs += [(f'{yolox}.bn.{t}', f'{mmdet}.bn.{t}')
                      for t in BN_KEYS]
    return pairs


def official_state_dict(checkpoint) -> Dict[str, torch.Tensor]:
    """The model weights of an official YOLOX checkpoint (``{'model':
    state_dict, ...}``, or the state dict itself; a ``module.`` prefix of
    a DDP save is dropped)."""
    state = checkpoint.get('model', checkpoint) \
        if isinstance(checkpoint, dict) else None
    if not isinstance(state, dict) or not state:
        raise ValueError('not a YOLOX checkpoint: expected a dict with the '
                         "model's state dict under 'model'")
    return {(k[len('module.'):] if k.startswith('module.') else k): v
            for k, v in state.items()}


def convert_official(state_dict: Dict[str, torch.Tensor],
                     rows: Sequence[Row]
                     ) -> 'OrderedDict[str, torch.Tensor]':
    """Rename an official YOLOX state dict to MMDet's keys (no folding).

    Raises:
        ValueError: A key of the table is missing, or the file has keys
            the table does not know (another model: YOLOX-Tiny, a YOLOX
            of other depth...); shapes are checked by the strict load of
            :func:`cbnet_tools.pretrained.load_strictly`.
    """
    pairs = _pairs(rows)
    known = {y for y, _ in pairs}
    missing = [y for y, _ in pairs if y not in state_dict]
    unexpected = [k for k in state_dict if k not in known]
    if missing or unexpected:
        raise ValueError(
            'not the YOLOX this converter maps (YOLOX-Nano): '
            f'{len(missing)} of its tensors missing '
            f'{missing[:3]}, {len(unexpected)} unknown tensors '
            f'{unexpected[:3]}')
    return OrderedDict((m, state_dict[y]) for y, m in pairs)


# -- the MMDet model -------------------------------------------------------

def build_mmdet_yolox(config: str = NANO_CONFIG,
                      num_classes: Optional[int] = None) -> torch.nn.Module:
    """MMDet's YOLOX of ``config`` (default: Nano, 80 classes), built, in
    eval mode (not initialised: a strict load replaces every tensor)."""
    from mmdet.registry import MODELS
    from mmengine.config import Config
    from mmengine.registry import init_default_scope
    if config.startswith('mmdet::'):
        from mmengine.hub import get_config
        cfg = get_config(config)
    else:
        cfg = Config.fromfile(config)
    init_default_scope('mmdet')
    model_cfg = cfg.model
    if num_classes is not None:
        model_cfg.bbox_head.num_classes = num_classes
    return MODELS.build(model_cfg).eval()


def raw_outputs(model: torch.nn.Module, images: torch.Tensor
                ) -> torch.Tensor:
    """What YOLOX's exported graph outputs: ``[B, points, 5 + classes]``,
    per anchor point of the strides 8/16/32 grids (row-major, level by
    level) the 4 raw box offsets, the objectness and the class scores
    after a sigmoid, not decoded.

    Args:
        model: MMDet's YOLOX.
        images (Tensor): ``float[B, 3, H, W]`` raw BGR 0-255 (MMDet's
            YOLOX preprocessor applies no mean or std).
    """
    with torch.no_grad():
        cls_scores, bbox_preds, objectness = model.bbox_head(
            model.neck(model.backbone(images)))
    levels = [torch.cat([reg, obj.sigmoid(), cls.sigmoid()], 1).flatten(2)
              for cls, reg, obj in zip(cls_scores, bbox_preds, objectness)]
    return torch.cat(levels, 2).permute(0, 2, 1)


# -- the class rows --------------------------------------------------------

#: The classifier tensors of MMDet's ``YOLOXHead`` (one per level).
CLS_PREFIX = 'bbox_head.multi_level_conv_cls.'


def map_class_rows(state_dict: Dict[str, torch.Tensor],
                   target: Sequence[str], source='coco',
                   aliases: Optional[Dict[str, str]] = None
                   ) -> 'OrderedDict[str, torch.Tensor]':
    """``state_dict`` with the head's classifier cut to ``target``'s
    classes, each row the row of its source class
    (:func:`cbnet_mmdet.utils.class_map.class_sources`: the same name, or
    its alias, ``rider`` from ``person``).

    Raises:
        ValueError: A target class has no source class (give it an alias,
            or fine-tune with a fresh classifier), or the head's rows are
            not one per source class.
    """
    from cbnet_mmdet.utils.class_map import class_sources, resolve_classes
    sources = class_sources(target, source, aliases)
    names = resolve_classes(target)
    lacking = [n for n, s in zip(names, sources) if s is None]
    if lacking:
        raise ValueError(f'no source class stands for {lacking}: give '
                         'each an alias, or start that classifier fresh')
    index = torch.tensor(sources, dtype=torch.long)
    num_source = len(resolve_classes(source))
    out, cut = OrderedDict(), 0
    for key, value in state_dict.items():
        if key.startswith(CLS_PREFIX):
            if value.shape[0] != num_source:
                raise ValueError(f'{key} has {value.shape[0]} rows, not one '
                                 f'per source class ({num_source})')
            value = value[index].clone()
            cut += 1
        out[key] = value
    if cut == 0:
        raise ValueError(f'no classifier tensors ({CLS_PREFIX}*) in the '
                         'state dict: not an MMDet YOLOX')
    return out


# -- fetching --------------------------------------------------------------

#: The ONNX export this converter was checked against (the project's
#: shared copy; YOLOX-ONNX-TFLite-Sample's ``model/yolox_nano.onnx``).
ONNX_SHA256 = ('695e750a5d5754bb5a8d5325643b59282191a7e7a564e435a415fd3c'
               '578eab14')
#: Megvii's official weights (YOLOX 0.1.1rc0 release asset); its sha256 is
#: recorded in the converted file's meta, not checked (not measured here:
#: the project's machines do not reach GitHub).
OFFICIAL_URL = ('https://github.com/Megvii-BaseDetection/YOLOX/releases/'
                'download/0.1.1rc0/yolox_nano.pth')
#: The largest output difference a converted ONNX model may show against
#: the file (measured on the shared copy: 2.4e-5 at 416x416).
MAX_OUTPUT_GAP = 1e-3


def street_path(path: str) -> str:
    """The 8-class twin of a converted COCO file: ``X.pth`` ->
    ``X_to-cityscapes-8.pth`` beside it."""
    stem, ext = osp.splitext(path)
    return f'{stem}_to-cityscapes-8{ext or ".pth"}'


def read_source(source: str) -> Tuple[str, bytes]:
    """(``'onnx'`` or ``'pth'``, the file's bytes) of a YOLOX-Nano file.

    Raises:
        FileNotFoundError: ``source`` does not exist.
        ValueError: Neither an ONNX file (``.onnx``) nor a PyTorch
            checkpoint.
    """
    import zipfile
    if not osp.isfile(source):
        raise FileNotFoundError(f'--source {source} not found')
    with open(source, 'rb') as f:
        data = f.read()
    if source.lower().endswith('.onnx'):
        return 'onnx', data
    # torch.save writes a zip archive (a pickle before PyTorch 1.6)
    if zipfile.is_zipfile(source) or data[:1] == b'\x80':
        return 'pth', data
    raise ValueError(f'--source {source}: neither an ONNX file (.onnx) nor '
                     "a PyTorch checkpoint (YOLOX's yolox_nano.pth)")


def fetch_yolox_nano(source: Optional[str] = None, out: Optional[str] = None,
                     log=print, download=None) -> Tuple[str, str]:
    """Convert YOLOX-Nano (COCO) to MMDet checkpoints in the cache.

    Writes the 80-class COCO model at ``out`` (default
    ``pretrained_path('yolox_nano')``) and its 8-class twin
    (:func:`street_path`: the classifier rows of the project's Cityscapes
    classes, ``rider`` from ``person``), each checked by a strict load into
    MMDet's YOLOX-Nano; an ONNX source is also run against the converted
    model when onnxruntime is installed.

    Args:
        source (str, optional): The ONNX export (its sha256 checked) or
            Megvii's ``yolox_nano.pth``; None downloads the latter from
            :data:`OFFICIAL_URL`.
        out (str, optional): The COCO checkpoint's path.
        log (callable): Progress printer.
        download (callable, optional): ``(url, dst)`` -> None; default
            ``torch.hub.download_url_to_file``.

    Returns:
        tuple[str, str]: The COCO and the 8-class checkpoints.

    Raises:
        ValueError: A sha256 mismatch, another model, or outputs that
            differ from the ONNX file's; nothing is written then.
    """
    import hashlib
    import os
    import tempfile

    from cbnet_mmdet.datasets.voc_fog import CITYSCAPES_CLASSES
    from cbnet_mmdet.utils.class_map import coco_classes, describe_map
    from cbnet_tools.pretrained import load_strictly, pretrained_path
    out = out or pretrained_path('yolox_nano')
    with tempfile.TemporaryDirectory() as tmp:
        if source is None:
            source = osp.join(tmp, 'yolox_nano.pth')
            log(f'downloading {OFFICIAL_URL}')
            (download or torch.hub.download_url_to_file)(OFFICIAL_URL, source)
        kind, data = read_source(source)
        digest = hashlib.sha256(data).hexdigest()
        rows = conv_table()
        model = build_mmdet_yolox()
        meta = dict(source=osp.basename(source), sha256=digest,
                    converted_by='tools/model_converters/fetch_pretrained.py'
                    ' yolox_nano', mmdet_config=NANO_CONFIG)
        if kind == 'onnx':
            from .yolox_onnx import convert_onnx, load_onnx, onnx_output_gap
            if digest != ONNX_SHA256:
                raise ValueError(
                    f'{source}: sha256 {digest}, expected {ONNX_SHA256}: not '
                    'the ONNX file this command converts (another export, '
                    'or a damaged copy); nothing written')
            state = convert_onnx(load_onnx(source), rows, model)
            meta['folded_batch_norms'] = True
        else:
            weights = torch.load(source, map_location='cpu',
                                 weights_only=True)
            state = convert_official(official_state_dict(weights), rows)
            meta['folded_batch_norms'] = False
            log(f'{osp.basename(source)}: sha256 {digest} (recorded; the '
                "release asset's hash is not pinned)")
        count = load_strictly(model, state)
        if kind == 'onnx':
            gap = onnx_output_gap(source, model)
            if gap is None:
                log('onnxruntime is not installed: the output check against '
                    'the ONNX file is skipped (pip install '
                    '"cbnet_mmdet[onnx]" to run it)')
            elif gap > MAX_OUTPUT_GAP:
                raise ValueError(
                    f'the converted model differs from {source} by {gap:.2e}'
                    f' (allowed {MAX_OUTPUT_GAP}): the convolutions are not '
                    "mapped as the file's graph runs them; nothing written")
            else:
                log(f'outputs equal to the ONNX file\'s within {gap:.1e} '
                    '(onnxruntime, one random input)')
            meta['onnx_output_gap'] = gap
    street = map_class_rows(state, CITYSCAPES_CLASSES)
    load_strictly(build_mmdet_yolox(num_classes=len(CITYSCAPES_CLASSES)),
                  street)
    os.makedirs(osp.dirname(osp.abspath(out)), exist_ok=True)
    written = []
    for path, weights, classes in (
            (out, state, coco_classes()),
            (street_path(out), street, CITYSCAPES_CLASSES)):
        file_meta = dict(meta, dataset_meta=dict(classes=tuple(classes)))
        if weights is street:
            file_meta['class_map'] = describe_map(classes)
        partial = path + '.partial'
        torch.save(dict(state_dict=weights, meta=file_meta), partial)
        os.replace(partial, path)  # never a half-written file at ``path``
        written.append(path)
    log(f'yolox_nano: {count} tensors, sha256 {digest[:12]}... -> {out} '
        f'(80 COCO classes) and {written[1]} (8 classes: '
        f'{describe_map(CITYSCAPES_CLASSES)})')
    return written[0], written[1]
