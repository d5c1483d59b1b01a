"""Clear-to-foggy teacher-EMA distillation (CBNet-DD, paper section II.E)."""
import copy
from typing import Tuple

import torch
from mmdet.models.detectors import SemiBaseDetector
from mmdet.registry import MODELS
from mmdet.structures import SampleList
from mmdet.utils import ConfigType, OptConfigType, OptMultiConfig
from torch import Tensor

from ..data_preprocessors.paired_data_preprocessor import IMG_CHANNELS
from .mask_call_recorder import (MaskCallRecorder, last_mask_modules,
                                 mask_logits_on)

EVAL_MODELS = ('student', 'teacher')


def select_label_channel(mask_logits: Tensor, labels: Tensor) -> Tensor:
    """Pick each RoI's ground-truth class channel from the mask logits.

    Args:
        mask_logits (Tensor): Tensor[N, C, h, w]; C = 1 for class-agnostic
            mask heads, else the number of classes.
        labels (Tensor): Tensor[N] ground-truth labels of the RoIs.

    Returns:
        Tensor: Tensor[N, h, w].
    """
    if mask_logits.size(1) == 1:
        return mask_logits[:, 0]
    index = torch.arange(mask_logits.size(0), device=mask_logits.device)
    return mask_logits[index, labels]


@MODELS.register_module()
class CBNetDistiller(SemiBaseDetector):
    """Student on foggy images, EMA teacher on the clear twins (CBNet-DD).

    Training input is a paired batch, Tensor[B, 6, H, W]: channels 0-2 the
    foggy image (student), 3-5 the clear image of the same scene with the
    same crop/flip/resize (teacher); build it with
    ``CBNetPairedFoggyDataset`` + ``CBNetLoadPairedImageFromFile`` and
    ``CBNetPairedDataPreprocessor``. One training step:

    1. the student computes its usual supervised losses on the foggy
       image, its parts called one by one as ``TwoStageDetector.loss``
       does (features, RPN, then its RoI head's own ``loss``); forward
       hooks (:class:`MaskCallRecorder`) read what its last mask head ran
       on: the positive RoIs of the last stage, their labels, its logits;
    2. the teacher (no gradients, eval mode) extracts features from the
       clear image and runs its last stage's mask RoI extractor and mask
       head on the SAME RoIs;
    3. ``loss_distill`` = ``distill_loss(student logits, teacher logits)``
       on each RoI's ground-truth class channel.

    The teacher is a frozen submodule (``requires_grad=False``): DDP does
    not reduce gradients for it, it is in ``state_dict`` (so checkpoints
    carry it and resume restores it), and ``CBNetTeacherEMAHook`` updates
    it as an EMA of the student after every optimizer step. A checkpoint of
    a plain detector (no ``student.``/``teacher.`` keys) loads into both
    (``SemiBaseDetector._load_from_state_dict``).

    Inference (validation and testing too) runs the model chosen by
    ``eval_with`` on channels 0-2 of a paired input, or on a plain 3-channel
    input; ``eval_with`` is set here only (``CBNetTeacherEMAHook`` leaves
    it alone).

    Args:
        detector (:obj:`ConfigDict` or dict): Config of the student; any
            MMDetection two-stage detector whose ``roi_head`` has a mask
            head fed by a mask RoI extractor (``StandardRoIHead`` with a
            ``mask_roi_extractor``, ``CascadeRoIHead``,
            ``CBNetCascadeRoIHead``) and calling its ``loss_mask`` as
            MMDet's ``FCNMaskHead`` does; another raises ``TypeError``
            (see :func:`last_mask_modules`).
        distill_loss (:obj:`ConfigDict` or dict): Distillation loss on
            mask logits, ``loss(student Tensor[N, h, w], teacher Tensor[N,
            h, w])``. Defaults to ``CBNetDistillLoss`` with weight 1.
        eval_with (str): ``'student'`` or ``'teacher'``: the model used by
            ``predict``/``_forward``/``extract_feat``. Defaults to
            ``'student'``.
        data_preprocessor (:obj:`ConfigDict` or dict, optional): Usually a
            ``CBNetPairedDataPreprocessor``.
        init_cfg (:obj:`ConfigDict` or list[:obj:`ConfigDict`] or dict or
            list[dict], optional): Initialization config.
    """

    def __init__(self,
                 detector: ConfigType,
                 distill_loss: ConfigType = dict(
                     type='CBNetDistillLoss', loss_weight=1.0),
                 eval_with: str = 'student',
                 data_preprocessor: OptConfigType = None,
                 init_cfg: OptMultiConfig = None) -> None:
        super().__init__(
            detector=detector,
            semi_train_cfg=dict(freeze_teacher=True),
            semi_test_cfg=dict(),
            data_preprocessor=data_preprocessor,
            init_cfg=init_cfg)
        if not getattr(self.student, 'with_mask', False):
            raise ValueError(
                f'CBNetDistiller: the student ({type(self.student).__name__}'
                f') has no mask head; distillation needs `roi_head` with a '
                f'`mask_head`')
        # the mask head's RoIs, labels and logits must be readable
        last_mask_modules(self.student.roi_head)
        self.distill_loss = MODELS.build(distill_loss)
        self.eval_with = eval_with

    @property
    def eval_with(self) -> str:
        """``'student'`` or ``'teacher'``: the model used at inference."""
        return self.semi_test_cfg['predict_on']

    @eval_with.setter
    def eval_with(self, which: str) -> None:
        if which not in EVAL_MODELS:
            raise ValueError(f'CBNetDistiller: eval_with must be one of '
                             f'{EVAL_MODELS}, got {which!r}')
        self.semi_test_cfg.update(
            predict_on=which, forward_on=which, extract_feat_on=which)

    def init_weights(self) -> None:
        """Initialise the student; the teacher starts as its copy."""
        super().init_weights()
        self.teacher.load_state_dict(self.student.state_dict())

    def train(self, mode: bool = True) -> 'CBNetDistiller':
        """Set training mode; the teacher always stays in eval mode."""
        super().train(mode)
        self.teacher.eval()
        return self

    @staticmethod
    def split_paired(batch_inputs: Tensor) -> Tuple[Tensor, Tensor]:
        """Split Tensor[B, 6, H, W] into foggy and clear Tensor[B, 3, H, W].

        Raises:
            ValueError: If the input does not have 6 channels.
        """
        if batch_inputs.dim() != 4 or \
                batch_inputs.size(1) != 2 * IMG_CHANNELS:
            raise ValueError(
                f'CBNetDistiller: training needs paired inputs Tensor[B, 6, '
                f'H, W] (foggy + clear, see CBNetLoadPairedImageFromFile and '
                f'CBNetPairedDataPreprocessor), got '
                f'{tuple(batch_inputs.shape)}')
        return batch_inputs[:, :IMG_CHANNELS], batch_inputs[:, IMG_CHANNELS:]

    @staticmethod
    def eval_inputs(batch_inputs: Tensor) -> Tensor:
        """The image inference runs on: the foggy half of a paired input."""
        return batch_inputs[:, :IMG_CHANNELS]

    def loss(self, batch_inputs: Tensor,
             batch_data_samples: SampleList) -> dict:
        """Supervised losses of the student plus ``loss_distill``.

        Args:
            batch_inputs (Tensor): Tensor[B, 6, H, W], normalised foggy
                (channels 0-2) and clear (3-5) images.
            batch_data_samples (list[:obj:`DetDataSample`]): Annotations
                (shared by both images).

        Returns:
            dict[str, Tensor]: The student's losses and ``loss_distill``.
        """
        foggy, clear = self.split_paired(batch_inputs)
        student = self.student
        x = student.extract_feat(foggy)
        losses, rpn_results_list = self.student_rpn_losses(
            x, batch_data_samples)
        with MaskCallRecorder(student.roi_head) as recorder:
            losses.update(
                student.roi_head.loss(x, rpn_results_list,
                                      batch_data_samples))
        call = recorder.last_call()
        if call is None:
            raise RuntimeError(
                f'CBNetDistiller: {type(student.roi_head).__name__} ran no '
                f'mask head (no proposal reached a mask stage), so there '
                f'are no mask logits to distil')
        with torch.no_grad():
            teacher_logits = mask_logits_on(
                self.teacher.roi_head, self.teacher.extract_feat(clear),
                call.rois)
        losses['loss_distill'] = self.distill_loss(
            select_label_channel(call.mask_preds, call.labels),
            select_label_channel(teacher_logits, call.labels))
        return losses

    def student_rpn_losses(self, x: Tuple[Tensor],
                           batch_data_samples: SampleList
                           ) -> Tuple[dict, list]:
        """The student's RPN losses and proposals, as
        ``TwoStageDetector.loss`` computes them (class-agnostic targets,
        ``train_cfg.rpn_proposal``; ``rpn_``-prefixed names), or the
        samples' precomputed ``proposals`` for a detector without RPN."""
        student = self.student
        if not student.with_rpn:
            return dict(), [s.proposals for s in batch_data_samples]
        proposal_cfg = student.train_cfg.get('rpn_proposal',
                                             student.test_cfg.rpn)
        rpn_data_samples = copy.deepcopy(batch_data_samples)
        for sample in rpn_data_samples:
            sample.gt_instances.labels = torch.zeros_like(
                sample.gt_instances.labels)
        rpn_losses, rpn_results_list = student.rpn_head.loss_and_predict(
            x, rpn_data_samples, proposal_cfg=proposal_cfg)
        losses = {(f'rpn_{k}' if 'loss' in k and 'rpn' not in k else k): v
                  for k, v in rpn_losses.items()}
        return losses, rpn_results_list

    def predict(self,
                batch_inputs: Tensor,
                batch_data_samples: SampleList,
                rescale: bool = True) -> SampleList:
        """Predict with ``eval_with`` on the foggy (or only) image.

        Args:
            batch_inputs (Tensor): Tensor[B, 3 or 6, H, W].
            batch_data_samples (list[:obj:`DetDataSample`]): Image metas.
            rescale (bool): Rescale results to the original image size.

        Returns:
            list[:obj:`DetDataSample`]: Detection results.
        """
        model = self.teacher if self.eval_with == 'teacher' \
            else self.student
        return model.predict(
            self.eval_inputs(batch_inputs), batch_data_samples,
            rescale=rescale)

    def _forward(self, batch_inputs: Tensor,
                 batch_data_samples: SampleList) -> tuple:
        """Raw head outputs of ``eval_with`` on the foggy (or only) image."""
        return super()._forward(
            self.eval_inputs(batch_inputs), batch_data_samples)

    def extract_feat(self, batch_inputs: Tensor) -> Tuple[Tensor]:
        """Features of ``eval_with`` on the foggy (or only) image."""
        return super().extract_feat(self.eval_inputs(batch_inputs))
