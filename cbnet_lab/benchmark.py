"""Helpers to build detectors from configs without weights and to measure
their cost (time, peak memory, parameters, FLOPs) on synthetic inputs.

Used by :mod:`cbnet_lab.model_benchmark`, :mod:`cbnet_lab.profiling`,
:mod:`cbnet_lab.component_benchmark` and the config tests. Nothing
is downloaded: every ``Pretrained`` initialisation and ``load_from`` is
dropped (:func:`cbnet_lab.config_edits.load_benchmark_cfg`), so the
models have random weights (speed and memory do not depend on the weight
values; detections after NMS do, slightly, see :func:`make_batch`). The
timing and memory measurements themselves (``time_calls``,
``time_alternately``, ``summarize``, ``PeakMemory``...) are
:mod:`cbnet_tools.measure`'s, imported here for the lab's modules.
"""
import copy
from typing import Dict, List, Optional, Tuple

import numpy as np
import torch
from mmengine.config import Config
from torch import nn

from cbnet_tools.measure import (  # noqa: F401  (the lab measures with them)
    PeakMemory, hwm_reset_works, set_malloc_thresholds, summarize,
    synchronize, time_alternately, time_calls)


def build_detector(cfg: Config, seed: Optional[int] = 0) -> nn.Module:
    """Build ``cfg.model`` with random initial weights, in the MMDet scope.

    Imports ``cfg.custom_imports`` and ``cbnet_mmdet`` first; MMEngine's
    per-parameter initialisation report is not logged (the current logger
    is set to warnings only). The weights are drawn after
    ``torch.manual_seed(seed)``, so every run measures the same model: with
    random weights the proposals, and through them the cost of the RoI
    heads (RoIAlign with ``sampling_ratio=0`` samples more points in larger
    RoIs), change with the weights.

    Args:
        cfg (Config): A config from
            :func:`cbnet_lab.config_edits.load_benchmark_cfg`.
        seed (int, optional): Seed of the initial weights; ``None`` leaves
            the global RNG alone. Defaults to 0.

    Returns:
        nn.Module: The detector (train mode, on CPU).
    """
    from mmdet.registry import MODELS
    from mmdet.utils import register_all_modules
    from mmengine.logging import MMLogger
    from mmengine.utils import import_modules_from_strings

    import cbnet_mmdet  # noqa: F401
    if cfg.get('custom_imports'):
        import_modules_from_strings(**cfg.custom_imports)
    register_all_modules(init_default_scope=True)
    MMLogger.get_instance('cbnet_benchmark', log_level='WARNING')
    if seed is not None:
        torch.manual_seed(seed)
    model = MODELS.build(cfg.model)
    model.init_weights()
    return model


def head_num_classes(model: nn.Module) -> List[int]:
    """``num_classes`` of every submodule that has one (heads).

    Args:
        model (nn.Module): A detector.

    Returns:
        list[int]: One entry per head (bbox stages, mask head, dense head).
    """
    return [
        m.num_classes for m in model.modules()
        if isinstance(getattr(m, 'num_classes', None), int)
    ]


def make_batch(batch_size: int = 1,
               size: Tuple[int, int] = (128, 256),
               num_items: int = 5,
               num_classes: int = 8,
               with_mask: bool = True,
               seed: int = 0,
               image: Optional[np.ndarray] = None) -> dict:
    """Un-preprocessed batch (``mmdet.testing.demo_mm_inputs``).

    The same seed gives the same images and ground truth, so every model is
    measured on the same inputs (each through its own data preprocessor).

    Args:
        batch_size (int): Images in the batch.
        size (tuple[int, int]): Image height and width, pixels.
        num_items (int): Ground-truth instances per image.
        num_classes (int): Labels are drawn from ``[1, num_classes)``.
        with_mask (bool): Add bitmap instance masks.
        seed (int): Seed of the torch RNG (the images use numpy's fixed
            seed inside ``demo_mm_inputs``).
        image (np.ndarray, optional): A photo (``H x W x 3`` uint8 BGR,
            as MMCV reads it) in place of the random images, resized to
            ``size`` (bilinear, as MMDet's ``Resize``); the ground truth
            stays synthetic.

    Returns:
        dict: ``inputs`` (list of ``Tensor[3, H, W]`` uint8) and
        ``data_samples`` (list of ``DetDataSample``).
    """
    from mmdet.testing import demo_mm_inputs
    photo = None if image is None else torch.from_numpy(
        np.ascontiguousarray(resize_image(image, size).transpose(2, 0, 1)))
    torch.manual_seed(seed)
    batch = demo_mm_inputs(
        batch_size=batch_size,
        image_shapes=[(3, *size)] * batch_size,
        num_items=[num_items] * batch_size,
        num_classes=num_classes,
        with_mask=with_mask)
    if photo is not None:
        batch['inputs'] = [photo.clone() for _ in range(batch_size)]
    return batch


def resize_image(image: np.ndarray, size: Tuple[int, int]) -> np.ndarray:
    """A ``H x W x 3`` uint8 image resized to ``size`` (height, width).

    Raises:
        ValueError: ``image`` is not ``H x W x 3`` uint8, or ``size`` is
            not two positive integers.
    """
    import mmcv
    if not (isinstance(image, np.ndarray) and image.ndim == 3 and
            image.shape[2] == 3 and image.dtype == np.uint8):
        raise ValueError('image must be an H x W x 3 uint8 array, got '
                         f'{getattr(image, "shape", type(image))}')
    h, w = (int(v) for v in size)
    if h < 1 or w < 1:
        raise ValueError(f'size must be (height, width) > 0, got {size}')
    if image.shape[:2] == (h, w):
        return image
    return mmcv.imresize(image, (w, h), interpolation='bilinear')


def pipeline_input_size(cfg: Config, size: Tuple[int, int]
                        ) -> Tuple[int, int]:
    """The size an image of ``size`` has after ``cfg``'s test pipeline.

    What MMDet's inference API (``DetInferencer``, the serving code) feeds
    the model for a camera frame of that size: the test pipeline's
    ``Resize`` (its ``scale`` with ``keep_ratio`` as MMDet computes it, or
    its fixed ``scale`` without; a ``scale_factor`` multiplies); before the
    data preprocessor's padding. A pipeline without ``Resize`` keeps the
    size.

    Args:
        cfg (Config): A detector config with a ``test_dataloader`` (or
            ``test_pipeline``).
        size (tuple[int, int]): Frame height and width, pixels.

    Returns:
        tuple[int, int]: Height and width the model sees.

    Raises:
        ValueError: The config has no test pipeline, or a ``Resize`` that
            this function cannot follow (several, or another type of
            resize whose output it does not know).
    """
    from mmcv.image import rescale_size
    loader = cfg.get('test_dataloader') or {}
    pipeline = (loader.get('dataset') or {}).get('pipeline') or \
        cfg.get('test_pipeline')
    if not pipeline:
        raise ValueError(f'{cfg.filename}: no test pipeline '
                         '(test_dataloader.dataset.pipeline) to read the '
                         'input size from')
    resizes = [t for t in pipeline if 'Resize' in str(t.get('type', ''))]
    if not resizes:
        return tuple(size)
    if len(resizes) > 1 or resizes[0]['type'] not in ('Resize',
                                                      'mmdet.Resize'):
        raise ValueError(
            f'{cfg.filename}: the test pipeline resizes with '
            f'{[t["type"] for t in resizes]}; only one MMDet Resize can be '
            'followed')
    t = resizes[0]
    h, w = size
    if t.get('scale') is not None:
        scale = t['scale']
        scale = (scale, scale) if isinstance(scale, int) else tuple(scale)
        if t.get('keep_ratio', False):
            w, h = rescale_size((w, h), scale)
        else:
            w, h = scale
    else:
        factor = t['scale_factor']
        fw, fh = (factor, factor) if isinstance(factor, (int, float)) \
            else factor
        w, h = int(w * fw + 0.5), int(h * fh + 0.5)
    return int(h), int(w)


def realistic_proposals(size: Tuple[int, int],
                        num: int = 1000,
                        min_side: float = 8.0,
                        max_side: float = 256.0,
                        seed: int = 0) -> torch.Tensor:
    """A fixed proposal set shaped like a trained RPN's output.

    Random weights make each model's RPN propose arbitrary boxes, and the
    cost of the RoI heads depends on them (RoIAlign with ``sampling_ratio=0``
    samples ``ceil(roi_size / output_size)`` points per bin, and the level
    of every RoI follows its size). The benchmark therefore feeds every
    two-stage model the same proposals: ``num`` boxes with centres uniform
    over the image, a scale ``sqrt(w * h)`` log-uniform in
    ``[min_side, max_side]`` pixels at a 512-pixel image height (scaled
    with the height: Cityscapes' instances at 1024x2048 are about 10 to 500
    pixels) and an aspect ratio ``h / w`` log-uniform in ``[0.5, 2]``
    (pedestrians to cars), clipped to the image; scores descend from 1.

    Args:
        size (tuple[int, int]): Image height and width, pixels.
        num (int): Proposals (the configs' k = 1000).
        min_side (float): Smallest scale at height 512, pixels.
        max_side (float): Largest scale at height 512, pixels.
        seed (int): Seed of a private generator.

    Returns:
        Tensor: ``Tensor[num, 4]`` boxes ``(x1, y1, x2, y2)``.
    """
    h, w = size
    if num < 1 or min_side <= 0 or max_side < min_side:
        raise ValueError(
            f'realistic_proposals: need num >= 1 and 0 < min_side <= '
            f'max_side, got num={num}, min_side={min_side}, '
            f'max_side={max_side}')
    gen = torch.Generator().manual_seed(seed)

    def log_uniform(low, high):
        u = torch.rand(num, generator=gen)
        return torch.exp(torch.log(torch.tensor(low)) + u * (
            torch.log(torch.tensor(high)) - torch.log(torch.tensor(low))))

    scale = log_uniform(min_side, max_side) * (h / 512)
    ratio = log_uniform(0.5, 2.0)
    bw, bh = scale / ratio.sqrt(), scale * ratio.sqrt()
    cx = torch.rand(num, generator=gen) * w
    cy = torch.rand(num, generator=gen) * h
    boxes = torch.stack([cx - bw / 2, cy - bh / 2, cx + bw / 2,
                         cy + bh / 2], dim=1)
    boxes[:, 0::2] = boxes[:, 0::2].clamp(0, w)
    boxes[:, 1::2] = boxes[:, 1::2].clamp(0, h)
    return boxes


class FixedProposals:
    """Feed a detector's RoI head a fixed proposal set at inference.

    Within the context, the detector's ``rpn_head.predict`` still runs (its
    cost is measured), but its result is replaced by
    :func:`realistic_proposals` for every image (the same boxes for every
    model). Only inference is affected: training samples a fixed number of
    RoIs from the proposals and the ground truth. A detector without an
    ``rpn_head`` (single-stage) is left alone.

    The number of proposals is, by default, what the model's RPN returns
    at test time (``test_cfg.rpn.max_per_img``): the first (top-scored)
    ``num`` boxes of the one 1000-box set, as a trained RPN that keeps
    fewer returns its best ones.

    Args:
        model (nn.Module): The detector.
        num (int, optional): Proposals per image; None: the RPN's
            ``test_cfg.max_per_img`` (1000 if it has none).
        seed (int): Seed of the proposal set.
    """

    def __init__(self, model: nn.Module, num: Optional[int] = None,
                 seed: int = 0) -> None:
        self.head = getattr(model, 'rpn_head', None)
        if num is None:
            test_cfg = getattr(self.head, 'test_cfg', None) or {}
            num = test_cfg.get('max_per_img', 1000)
        self.num, self.seed = num, seed

    def _predict(self, x, batch_data_samples, rescale=False):
        from mmengine.structures import InstanceData
        results = self._original(x, batch_data_samples, rescale=rescale)
        fixed = []
        for result, sample in zip(results, batch_data_samples):
            boxes = realistic_proposals(
                sample.metainfo['img_shape'], max(self.num, 1000),
                seed=self.seed)[:self.num]
            boxes = boxes.to(result.bboxes.device, result.bboxes.dtype)
            fixed.append(InstanceData(
                bboxes=boxes,
                scores=torch.linspace(1, 0.01, len(boxes)).to(boxes),
                labels=boxes.new_zeros(len(boxes), dtype=torch.long)))
        return fixed

    def __enter__(self):
        if self.head is not None:
            # an instance attribute already (a profiler's wrapper) is put
            # back on exit; otherwise the class's method shows again
            self._own = vars(self.head).get('predict')
            self._original = self.head.predict
            self.head.predict = self._predict
        return self

    def __exit__(self, *exc):
        if self.head is not None:
            if self._own is None:
                del self.head.predict
            else:
                self.head.predict = self._own
        return False


def preprocess(model: nn.Module, batch: dict, training: bool) -> dict:
    """Run the model's data preprocessor on a copy of ``batch``.

    Args:
        model (nn.Module): The detector (already on ``device``).
        batch (dict): From :func:`make_batch`.
        training (bool): Training mode of the preprocessor (it also
            moves the data to the model's device).

    Returns:
        dict: ``inputs`` (``Tensor[B, 3, H', W']``, padded) and
        ``data_samples``.
    """
    return model.data_preprocessor(copy.deepcopy(batch), training)


def has_mask_head(model: nn.Module) -> bool:
    """Whether the detector predicts masks."""
    roi_head = getattr(model, 'roi_head', None)
    return bool(getattr(roi_head, 'with_mask', False))


def train_step(model: nn.Module, data: dict,
               optim_wrapper=None) -> torch.Tensor:
    """One training step: loss forward, backward, optimiser step.

    Args:
        model (nn.Module): The detector in train mode.
        data (dict): A preprocessed batch (:func:`preprocess`, training).
        optim_wrapper (OptimWrapper, optional): Steps and zeroes the
            gradients; without it only forward and backward run.

    Returns:
        Tensor: The total loss (scalar, detached).
    """
    losses = model(**data, mode='loss')
    loss, _ = model.parse_losses(losses)
    if optim_wrapper is not None:
        optim_wrapper.update_params(loss)
    else:
        loss.backward()
    return loss.detach()


def count_params(model: nn.Module) -> int:
    """Number of parameters (trainable or not)."""
    return sum(p.numel() for p in model.parameters())


def count_flops(model: nn.Module, data: dict) -> Dict[str, float]:
    """GFLOPs of one inference, by PyTorch's ``FlopCounterMode``.

    Counts the ATen operators that run (matrix products, convolutions,
    attention), so data-dependent work (RPN, RoI heads on the proposals
    actually kept, masks of the detections actually made) is included as
    executed; PyTorch's fused CPU attention is counted as its two matrix
    products. mmcv's compiled operators (deformable convolution, RoIAlign)
    and element-wise operators count as zero, so the figures are lower
    bounds. One multiply-add counts as one FLOP (fvcore's and MMDet's
    convention; PyTorch counts two, halved here).

    Args:
        model (nn.Module): The detector in eval mode.
        data (dict): A preprocessed batch (:func:`preprocess`).

    Returns:
        dict: ``predict`` (the whole inference) and ``features`` (backbone
        and neck only, independent of the weights), GFLOPs per batch.
    """
    from torch.utils.flop_counter import FlopCounterMode, sdpa_flop_count

    def cpu_sdpa(query, key, value, *args, out_shape=None, **kwargs):
        return sdpa_flop_count(query, key, value)

    # PyTorch counts its fused CUDA attention kernels but not the fused CPU
    # one, which MiT's attention runs on the CPU: without this its attention
    # would count zero
    cpu_op = getattr(torch.ops.aten,
                     '_scaled_dot_product_flash_attention_for_cpu', None)
    mapping = {cpu_op: cpu_sdpa} if cpu_op is not None else {}
    out = {}
    with torch.no_grad():
        for part, run in (
            ('predict', lambda: model(**data, mode='predict')),
            ('features', lambda: model.extract_feat(data['inputs'])),
        ):
            with FlopCounterMode(display=False,
                                 custom_mapping=mapping) as counter:
                run()
            out[part] = counter.get_total_flops() / 2 / 1e9
    return out
