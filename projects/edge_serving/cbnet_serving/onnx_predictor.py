"""An exported detector (:mod:`.export`) on ONNX Runtime behind the same
``predict`` call as :class:`.predictor.Predictor`.

The preprocessing is the config's test pipeline as the file's metadata
records it: resize as MMDet's ``Resize`` does (``mmcv.imrescale`` when it
keeps the aspect ratio), pad bottom and right with the preprocessor's pad
value to its ``pad_size_divisor`` (or to the graph's fixed input shape,
when it was exported with one); the graph's boxes are divided by
the scale factor, as MMDet's head rescales them. An image that the resize
would make larger than a fixed input shape (a portrait photo under a
landscape scale) is shrunk further to fit; :attr:`OnnxPredictor.shrunk`
counts them. Needs only NumPy, OpenCV (through mmcv's image functions) and
``onnxruntime`` (``pip install "cbnet_mmdet[onnx]"``), no PyTorch.
"""
import json
import os
import os.path as osp
from typing import Dict, List, Optional, Tuple

import mmcv
import numpy as np

#: The metadata key and layout :mod:`.export` writes.
META_KEY = 'cbnet_mmdet'
META_FORMAT = 1


def _ort():
    try:
        import onnxruntime
    except ImportError:
        raise ImportError(
            'running an exported model needs onnxruntime: pip install '
            '"cbnet_mmdet[onnx]" (or onnxruntime==1.32.0)') from None
    return onnxruntime


def letterbox(img: np.ndarray, meta: Dict) -> Tuple[np.ndarray, Tuple[
        float, float], bool]:
    """``img`` (H x W x 3) as the graph's input ``(1, 3, H, W)`` float32,
    the scale factor ``(w_scale, h_scale)`` and whether it had to be
    shrunk below the pipeline's size to fit the input shape.

    Raises:
        ValueError: ``img`` is not an H x W x 3 array (as the configs'
            ``CBNetCheckImage`` refuses it)."""
    if not isinstance(img, np.ndarray) or img.ndim != 3 or \
            img.shape[2] != 3 or min(img.shape[:2]) < 1:
        raise ValueError(
            'the exported model takes H x W x 3 BGR images, got '
            f"{getattr(img, 'shape', type(img).__name__)}")
    rule = meta['resize']
    scale = tuple(rule['scale'])
    if rule['keep_ratio']:
        resized = mmcv.imrescale(img, scale, interpolation='bilinear',
                                 backend='cv2')
    else:
        resized = mmcv.imresize(img, scale, interpolation='bilinear',
                                backend='cv2')
    h, w = resized.shape[:2]
    if meta['input_shape'] is None:  # any size: padded as MMDet pads it
        div = int(meta['pad_size_divisor'])
        height, width = -(-h // div) * div, -(-w // div) * div
    else:
        height, width = meta['input_shape']
    shrunk = h > height or w > width
    if shrunk:
        fit = min(height / h, width / w)
        resized = mmcv.imresize(
            resized, (max(1, int(w * fit)), max(1, int(h * fit))),
            interpolation='bilinear', backend='cv2')
        h, w = resized.shape[:2]
    batch = np.full((1, 3, height, width), meta['pad_value'],
                    dtype=np.float32)
    batch[0, :, :h, :w] = resized.transpose(2, 0, 1)
    return batch, (w / img.shape[1], h / img.shape[0]), shrunk


class OnnxPredictor:
    """An exported detector file on ONNX Runtime.

    Args:
        path (str): the ``.onnx`` file of ``export_onnx.py``.
        threads (int, optional): ONNX Runtime's intra-op threads; default
            ``OMP_NUM_THREADS`` when set, else ONNX Runtime's own choice.

    Raises:
        FileNotFoundError: No such file.
        ValueError: Not an ONNX model, or one without the exporter's
            metadata (how to resize and pad, the class names).
    """

    def __init__(self, path: str, threads: Optional[int] = None) -> None:
        if not osp.isfile(path):
            raise FileNotFoundError(f'ONNX file {path} not found')
        ort = _ort()
        options = ort.SessionOptions()
        if threads is None and os.environ.get('OMP_NUM_THREADS'):
            threads = int(os.environ['OMP_NUM_THREADS'])
        if threads:
            options.intra_op_num_threads = int(threads)
            options.inter_op_num_threads = 1
        options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        options.log_severity_level = 3  # errors only
        try:
            self.session = ort.InferenceSession(
                path, options, providers=['CPUExecutionProvider'])
        except Exception as err:  # ORT's InvalidProtobuf, Fail, ...
            raise ValueError(f'{path} is not a model ONNX Runtime can '
                             f'load: {err}') from err
        custom = self.session.get_modelmeta().custom_metadata_map
        if META_KEY not in custom:
            raise ValueError(
                f'{path} has no {META_KEY!r} metadata (how to resize and '
                'pad, the class names): export it with projects/'
                'edge_serving/tools/export_onnx.py')
        self.meta = json.loads(custom[META_KEY])
        if self.meta.get('format') != META_FORMAT:
            raise ValueError(
                f"{path}: metadata format {self.meta.get('format')!r}, this "
                f'code reads {META_FORMAT}: export it again')
        self.path = path
        self.threads = threads
        self.input_name = self.session.get_inputs()[0].name
        self.shrunk = 0

    def predict(self, images: List[np.ndarray]) -> List[Dict]:
        """Detect on BGR uint8 images, one at a time (the graph takes one);
        one dict per image: ``labels``, ``scores``, ``bboxes`` (x1y1x2y2
        in the input image's pixels), as ``DetInferencer``'s
        ``pred2dict``."""
        out = []
        for img in images:  # BGR: a bgr_to_rgb preprocessor is in the graph
            batch, (w_scale, h_scale), shrunk = letterbox(img, self.meta)
            self.shrunk += int(shrunk)
            boxes, scores, labels = self.session.run(
                None, {self.input_name: batch})
            boxes = boxes / np.array([w_scale, h_scale, w_scale, h_scale],
                                     dtype=np.float32)
            out.append(dict(labels=labels.astype(int).tolist(),
                            scores=scores.astype(float).tolist(),
                            bboxes=boxes.astype(float).tolist()))
        return out

    def info(self) -> Dict:
        """What the router records of its local model."""
        return dict(
            config=self.meta.get('config'),
            checkpoint=self.meta.get('checkpoint'),
            weights=f'ONNX {osp.basename(self.path)}',
            device='cpu (ONNX Runtime)', classes=list(self.meta['classes']),
            model=f"{self.meta.get('model')} (ONNX Runtime)",
            input_shape=self.meta['input_shape'] or
            f"any, padded to {self.meta['pad_size_divisor']}",
            threads=self.threads,
            shrunk_to_fit=self.shrunk)
