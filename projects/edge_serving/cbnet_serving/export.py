"""An MMDet YOLOX as one ONNX file, run the way an edge device runs it.

:func:`export_yolox` traces a YOLOX detector of a config and its
checkpoint (MMDet's ``YOLOX``: backbone, neck and ``YOLOXHead`` called
explicitly, the way the detector's ``predict`` calls them) into an ONNX
graph that takes one letterboxed image and returns the detections: the
network, then the head's decoding and class-aware NMS as
``YOLOXHead.predict_by_feat`` does them (sigmoid class scores times
sigmoid objectness, the best class per prior, ``test_cfg.score_thr``,
``batched_nms`` at ``test_cfg.nms.iou_threshold``, every box NMS keeps, by
descending score). MMDet's own ``_bbox_decode`` decodes the boxes; the
priors are MMDet's ``MlvlPointGenerator`` grid, computed in the graph
from the feature sizes (:meth:`YOLOXGraph.grid`, tested against MMDet's)
so that the graph takes any input size, or, for a fixed ``shape``, MMDet's
own grid stored as a constant. NMS is ONNX's ``NonMaxSuppression`` (ONNX
Runtime suppresses at IoU > threshold, as mmcv's ``nms``).

What the graph does not hold is what an application does around it, and
:class:`.onnx_predictor.OnnxPredictor` does that as the config's test
pipeline and data preprocessor do: resize keeping the aspect ratio to fit
the config's ``Resize`` scale (``mmcv.imrescale``), pad bottom and right
with the preprocessor's ``pad_value`` to its ``pad_size_divisor`` (or to
the fixed shape), and divide the boxes by the scale factor. All of it is
recorded in the file's metadata (``metadata_props['cbnet_mmdet']``,
JSON), so the file alone is enough to run it.

By default the input size is free: every image gets exactly the input
the PyTorch model gets, and the detections are the PyTorch model's (to
float rounding). A fixed ``shape`` (some edge runtimes want one) pads
every image to it: where that is more than the eager model's padding the
border differs and a few boxes may too (``detections_gap`` says so); an
image the resize would make larger than the shape is shrunk further to
fit and the predictor counts it.

Needs ``onnx`` (``pip install "cbnet_mmdet[onnx]"``); the check
(:func:`detections_gap`) also ``onnxruntime``.
"""
import hashlib
import json
import math
import os
import os.path as osp
import sys
from datetime import datetime, timezone
from typing import Dict, Optional, Sequence, Tuple

import torch
from torch import nn

#: The metadata key of the exported file.
META_KEY = 'cbnet_mmdet'
#: Version of the metadata layout.
META_FORMAT = 1
#: Test-pipeline transforms that the predictor does (or that do nothing
#: at inference); any other is refused: the graph would not see it.
KNOWN_TRANSFORMS = ('LoadImageFromFile', 'CBNetLoadImageFromFile',
                    'CBNetCheckImage', 'LoadAnnotations', 'Resize',
                    'PackDetInputs')


class _NonMaxSuppression(torch.autograd.Function):
    """mmcv's ``nms`` in PyTorch, ONNX's ``NonMaxSuppression`` in the
    exported graph: indices of the kept boxes by descending score."""

    @staticmethod
    def forward(ctx, boxes, scores, iou_threshold: float,
                score_threshold: float):
        from mmcv.ops import nms
        valid = torch.nonzero(scores > score_threshold).squeeze(1)
        if valid.numel() == 0:
            return valid
        _, keep = nms(boxes[valid], scores[valid], iou_threshold)
        return valid[keep]

    @staticmethod
    def symbolic(g, boxes, scores, iou_threshold, score_threshold):
        boxes = g.op('Unsqueeze', boxes, axes_i=[0])
        scores = g.op('Unsqueeze', scores, axes_i=[0, 1])
        selected = g.op(
            'NonMaxSuppression', boxes, scores,
            g.op('Constant',
                 value_t=torch.tensor([sys.maxsize], dtype=torch.long)),
            g.op('Constant', value_t=torch.tensor([float(iou_threshold)])),
            g.op('Constant',
                 value_t=torch.tensor([float(score_threshold)])))
        # rows (batch, class, box): the box column
        column = g.op('Gather', selected,
                      g.op('Constant', value_t=torch.tensor(2)), axis_i=1)
        return column


class YOLOXGraph(nn.Module):
    """A YOLOX detector for any (or one fixed) input shape, decoding and
    NMS included: ``(1, 3, H, W)`` float pixels in the preprocessor's channel
    order and range (raw BGR 0-255 for MMDet's YOLOX) to ``boxes`` (K, 4,
    x1y1x2y2 in input pixels), ``scores`` (K,), ``labels`` (K,)."""

    def __init__(self, detector: nn.Module,
                 shape: Optional[Tuple[int, int]] = None) -> None:
        super().__init__()
        self.detector = detector
        head = detector.bbox_head
        cfg = head.test_cfg
        self.score_thr = float(cfg.score_thr)
        self.iou_threshold = float(cfg.nms.iou_threshold)
        generator = head.prior_generator
        self.strides = [tuple(float(v) for v in s)
                        for s in generator.strides]
        self.offset = float(generator.offset)
        self.fixed = shape is not None
        if self.fixed:
            # MMDet's own grid for the one input shape, as a constant
            with torch.no_grad():
                feats = detector.extract_feat(torch.zeros(1, 3, *shape))
            priors = generator.grid_priors(
                [f.shape[-2:] for f in feats], dtype=torch.float32,
                device='cpu', with_stride=True)
            self.register_buffer('priors', torch.cat(priors),
                                 persistent=False)
        pre = detector.data_preprocessor
        self.bgr_to_rgb = bool(getattr(pre, '_channel_conversion', False))
        self.normalize = bool(getattr(pre, '_enable_normalize', False))
        if self.normalize:
            self.register_buffer('mean', pre.mean.detach().clone(),
                                 persistent=False)
            self.register_buffer('std', pre.std.detach().clone(),
                                 persistent=False)

    def grid(self, feats: Sequence[torch.Tensor]) -> torch.Tensor:
        """MMDet's ``MlvlPointGenerator.grid_priors`` (with strides) of
        the feature maps, computed from their traced sizes, so that the
        graph takes any input size (MMDet's own generator turns the
        sizes into constants when traced)."""
        levels = []
        for feat, (sw, sh) in zip(feats, self.strides):
            ys = (torch.arange(feat.shape[2], dtype=torch.float32) +
                  self.offset) * sh
            xs = (torch.arange(feat.shape[3], dtype=torch.float32) +
                  self.offset) * sw
            yy, xx = torch.meshgrid(ys, xs, indexing='ij')
            xx, yy = xx.reshape(-1), yy.reshape(-1)
            levels.append(torch.stack(
                [xx, yy, torch.full_like(xx, sw), torch.full_like(yy, sh)],
                -1))
        return torch.cat(levels)

    def forward(self, images: torch.Tensor):
        if self.bgr_to_rgb:
            images = images[:, [2, 1, 0]]
        if self.normalize:
            images = (images - self.mean) / self.std
        head = self.detector.bbox_head
        cls_scores, bbox_preds, objectnesses = head(
            self.detector.extract_feat(images))
        cls = torch.cat([c.permute(0, 2, 3, 1).reshape(
            -1, head.cls_out_channels) for c in cls_scores]).sigmoid()
        deltas = torch.cat(
            [b.permute(0, 2, 3, 1).reshape(-1, 4) for b in bbox_preds])
        obj = torch.cat(
            [o.permute(0, 2, 3, 1).reshape(-1) for o in objectnesses]).sigmoid()
        priors = self.priors if self.fixed else self.grid(cls_scores)
        bboxes = head._bbox_decode(priors, deltas[None])[0]
        max_scores, labels = cls.max(1)
        scores = max_scores * obj
        # class-aware NMS in one call, as mmcv's batched_nms: each class's
        # boxes moved apart by more than the largest coordinate
        offsets = labels.to(bboxes) * (bboxes.max() + 1)
        keep = _NonMaxSuppression.apply(bboxes + offsets[:, None], scores,
                                        self.iou_threshold, self.score_thr)
        return bboxes[keep], scores[keep], labels[keep]


def _resize_rule(cfg) -> Dict:
    """The test pipeline's resize (``scale`` (w, h), ``keep_ratio``);
    refuses a transform the predictor would not do."""
    pipeline = cfg.test_dataloader.dataset.get('pipeline') or []
    resize = None
    for t in pipeline:
        kind = t.get('type')
        if kind not in KNOWN_TRANSFORMS:
            raise ValueError(
                f'the test pipeline holds {kind!r}, which the exported '
                f'model would not run (known: {", ".join(KNOWN_TRANSFORMS)})')
        if kind == 'Resize':
            resize = t
    if resize is None or resize.get('scale') is None:
        raise ValueError('the test pipeline has no Resize with a scale: '
                         'the exported model needs a fixed input size')
    return dict(scale=[int(v) for v in resize['scale']],
                keep_ratio=bool(resize.get('keep_ratio', False)))


def default_shape(rule: Dict, divisor: int = 32) -> Tuple[int, int]:
    """The input shape (H, W) holding the resize scale, rounded up to
    ``divisor``."""
    w, h = rule['scale']
    return (int(math.ceil(h / divisor) * divisor),
            int(math.ceil(w / divisor) * divisor))


def _sha256(path: str) -> str:
    digest = hashlib.sha256()
    with open(path, 'rb') as f:
        for block in iter(lambda: f.read(1 << 20), b''):
            digest.update(block)
    return digest.hexdigest()


def build_detector(config: str, checkpoint: Optional[str]):
    """The detector of ``config`` in eval mode with ``checkpoint`` loaded
    (strictly: a checkpoint of another model is refused), its config and
    the checkpoint's ``meta`` (empty without one).

    Raises:
        FileNotFoundError: No config or checkpoint file.
        ValueError: Not a YOLOX detector, or preprocessing the graph cannot
            hold (a dehazer, batch augments at test time).
    """
    from mmengine.config import Config
    from mmengine.registry import init_default_scope
    from mmengine.runner import load_checkpoint

    from mmdet.registry import MODELS
    if not osp.isfile(config):
        raise FileNotFoundError(f'config file {config} not found')
    if checkpoint is not None and not osp.isfile(checkpoint):
        raise FileNotFoundError(f'checkpoint file {checkpoint} not found')
    cfg = Config.fromfile(config)
    if cfg.model.get('type') != 'YOLOX' or \
            cfg.model.get('bbox_head', {}).get('type') != 'YOLOXHead':
        raise ValueError(
            f'{config}: the exporter takes an MMDet YOLOX (type YOLOX with '
            f'a YOLOXHead), not {cfg.model.get("type")!r}')
    pre = cfg.model.get('data_preprocessor', {})
    if pre.get('type') != 'DetDataPreprocessor':
        raise ValueError(
            f'{config}: its data preprocessor {pre.get("type")!r} is not '
            "MMDet's DetDataPreprocessor: what it does (a dehazer in front, "
            'say) would not be in the exported graph')
    init_default_scope(cfg.get('default_scope', 'mmdet'))
    detector = MODELS.build(cfg.model)
    meta = {}
    if checkpoint is not None:
        loaded = load_checkpoint(detector, checkpoint, map_location='cpu',
                                 strict=True, revise_keys=[])
        meta = dict(loaded.get('meta') or {})
    detector.eval()
    return detector, cfg, meta


def export_yolox(config: str, checkpoint: Optional[str], out: str,
                 shape: Optional[Sequence[int]] = None,
                 opset: int = 11) -> Dict:
    """Export ``config`` + ``checkpoint`` to ``out`` (ONNX); the metadata
    written into the file is returned.

    Args:
        shape: a fixed input (H, W); default any size, the image padded
            to the preprocessor's ``pad_size_divisor`` as MMDet pads it.

    Raises:
        ValueError: see :func:`build_detector`; a shape not a multiple of
            the largest stride; a test pipeline the predictor cannot redo.
    """
    import onnx

    detector, cfg, ckpt_meta = build_detector(config, checkpoint)
    rule = _resize_rule(cfg)
    strides = [s[0] if isinstance(s, (list, tuple)) else s
               for s in detector.bbox_head.prior_generator.strides]
    pre = cfg.model.data_preprocessor
    divisor = int(pre.get('pad_size_divisor', 1))
    if divisor % max(strides):
        raise ValueError(f'pad_size_divisor {divisor} is not a multiple '
                         f'of the largest stride {max(strides)}')
    if shape is not None:
        shape = tuple(int(v) for v in shape)
        if len(shape) != 2 or min(shape) < 1 or \
                any(v % max(strides) for v in shape):
            raise ValueError(
                f'input shape {shape} must be two positive multiples of '
                f'the largest stride {max(strides)}')
    graph = YOLOXGraph(detector, shape).eval()
    example = shape or default_shape(rule, divisor)
    meta = dict(
        format=META_FORMAT, model='YOLOX',
        input_shape=list(shape) if shape else None,
        pad_size_divisor=divisor, resize=rule,
        pad_value=float(pre.get('pad_value', 0)),
        channel_order='rgb' if graph.bgr_to_rgb else 'bgr',
        score_thr=graph.score_thr, iou_threshold=graph.iou_threshold,
        classes=list(_config_classes(cfg)),
        config=osp.basename(config),
        checkpoint=osp.basename(checkpoint) if checkpoint else None,
        checkpoint_sha256=_sha256(checkpoint) if checkpoint else None,
        torch=torch.__version__, opset=opset,
        date=datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC'))
    classes = (ckpt_meta.get('dataset_meta') or {}).get('classes')
    if classes:  # what the checkpoint was trained on names the labels
        meta['classes'] = list(classes)
    if len(meta['classes']) != detector.bbox_head.num_classes:
        raise ValueError(
            f'{config}: {len(meta["classes"])} class names for a head of '
            f'{detector.bbox_head.num_classes} classes')
    os.makedirs(osp.dirname(osp.abspath(out)), exist_ok=True)
    with torch.no_grad():
        torch.onnx.export(
            graph, (torch.zeros(1, 3, *example), ), out, dynamo=False,
            opset_version=opset, input_names=['image'],
            output_names=['boxes', 'scores', 'labels'],
            dynamic_axes=dict(
                {} if shape else {'image': {2: 'height', 3: 'width'}},
                boxes={0: 'detections'}, scores={0: 'detections'},
                labels={0: 'detections'}))
    model = onnx.load(out)
    entry = model.metadata_props.add()
    entry.key, entry.value = META_KEY, json.dumps(meta)
    onnx.save(model, out)
    return meta


def _config_classes(cfg) -> Sequence[str]:
    """The class names of the config's test dataset (its metainfo or its
    class's METAINFO)."""
    from mmdet.registry import DATASETS
    dataset = cfg.test_dataloader.dataset
    metainfo = dataset.get('metainfo') or {}
    if metainfo.get('classes'):
        return list(metainfo['classes'])
    cls = DATASETS.get(dataset.get('type'))
    return list(getattr(cls, 'METAINFO', {}).get('classes', ()))


def detections_gap(onnx_file: str, config: str, checkpoint: Optional[str],
                   images: Sequence) -> Dict:
    """The exported file's detections against the PyTorch model's
    (``DetInferencer``, the serving code's :class:`.predictor.Predictor`)
    on ``images`` (BGR arrays): per image both counts, whether they hold
    the same labels, the largest box gap (pixels: each ONNX box to the
    nearest PyTorch box of its label; detections of equal score may come
    in either order) and score gap (the sorted scores), and whether both saw the same input (the
    eager model pads to its divisor; a graph of a fixed shape to that
    shape: where those differ, the border differs and so may a few
    boxes)."""
    import numpy as np
    from mmengine.dataset import pseudo_collate

    from .onnx_predictor import OnnxPredictor, letterbox
    from .predictor import Predictor
    eager = Predictor(config, checkpoint)
    graph = OnnxPredictor(onnx_file, threads=1)
    rows = []
    for img in images:
        want = eager.predict([img])[0]
        got = graph.predict([img])[0]
        batch, _, _ = letterbox(img, graph.meta)
        data = eager.inferencer.model.data_preprocessor(
            pseudo_collate([eager.inferencer.pipeline(img)]), False)
        box, score = _gap(want, got)
        rows.append(dict(
            torch_detections=len(want['scores']),
            onnx_detections=len(got['scores']),
            labels_equal=sorted(want['labels']) == sorted(got['labels']),
            max_box_gap=box, max_score_gap=score,
            same_input=list(data['inputs'].shape[-2:]) ==
            list(batch.shape[-2:])))
    return dict(images=rows, equal=all(
        r['torch_detections'] == r['onnx_detections'] and r['labels_equal']
        for r in rows))


def _gap(want: Dict, got: Dict) -> Tuple[float, float]:
    """Largest box gap (each of ``got``'s boxes to the nearest of
    ``want``'s with its label) and largest gap of the sorted scores."""
    import numpy as np
    wb, gb = np.asarray(want['bboxes']), np.asarray(got['bboxes'])
    wl, gl = np.asarray(want['labels']), np.asarray(got['labels'])
    box = 0.
    for b, label in zip(gb, gl):
        same = wb[wl == label]
        box = max(box, float(np.abs(same - b).max(1).min())
                  if len(same) else float('inf'))
    ws, gs = sorted(want['scores']), sorted(got['scores'])
    n = min(len(ws), len(gs))
    score = float(np.abs(np.asarray(ws[-n:]) - np.asarray(gs[-n:])).max()) \
        if n else 0.
    return box, score
