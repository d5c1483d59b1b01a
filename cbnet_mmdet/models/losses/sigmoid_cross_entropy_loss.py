"""Per-class sigmoid BCE for RoI classification (paper II.C.1, eq. (4))."""
from typing import Dict

import torch
from mmdet.models.losses import CrossEntropyLoss, accuracy
from mmdet.registry import MODELS
from torch import Tensor


@MODELS.register_module()
class CBNetSigmoidCrossEntropyLoss(CrossEntropyLoss):
    """Binary cross-entropy per object class, no background logit.

    Paper eq. (4) trains each cascade stage's classifier with binary
    cross-entropy: every RoI gets ``C`` independent sigmoid outputs, the
    target is the one-hot of its class and all zeros for background. This is
    MMDet's ``CrossEntropyLoss(use_sigmoid=True)`` on ``C`` channels (a
    background label ``C`` expands to an all-zero row), summed over classes
    and averaged over the sampled RoIs; the bbox head learns no background
    logit.

    It also supplies what MMDet's ``BBoxHead`` asks a custom classification
    loss for (the hooks Seesaw loss uses), so it drops into any
    ``Shared2FCBBoxHead`` and MMDet's cascade:

    - ``get_cls_channels(C) = C``: the classifier has ``C`` outputs;
    - ``get_activation``: ``[sigmoid(x), prod(1 - sigmoid(x))]``: class
      probabilities plus, as the last column MMDet drops for NMS and box
      refinement, the probability that no class is present;
    - ``get_accuracy``: the accuracy of the arg-max over those ``C + 1``
      columns, logged as ``acc`` like MMDet's softmax heads.

    With MMDet's softmax ``CrossEntropyLoss`` instead (``C + 1`` outputs),
    the cascade is MMDet's usual one; the paper configs use this loss.

    Args:
        loss_weight (float): Weight of the loss. Defaults to 1.0.
        **kwargs: Other arguments of :class:`CrossEntropyLoss`
            (``reduction``, ``class_weight``); ``use_sigmoid`` and
            ``use_mask`` are fixed.
    """

    def __init__(self, loss_weight: float = 1.0, **kwargs) -> None:
        for key in ('use_sigmoid', 'use_mask'):
            if key in kwargs:
                raise TypeError(
                    f'CBNetSigmoidCrossEntropyLoss: {key} is fixed (a '
                    'sigmoid BCE over the classes); use CrossEntropyLoss '
                    'for other variants')
        super().__init__(use_sigmoid=True, loss_weight=loss_weight, **kwargs)
        self.custom_cls_channels = True
        self.custom_activation = True
        self.custom_accuracy = True

    def get_cls_channels(self, num_classes: int) -> int:
        """Classifier outputs: one logit per object class, no background.

        Args:
            num_classes (int): Number of object classes ``C``.

        Returns:
            int: ``C``.
        """
        return num_classes

    def get_activation(self, cls_score: Tensor) -> Tensor:
        """Class probabilities with a background column appended.

        Args:
            cls_score (Tensor): Logits ``Tensor[N, C]``.

        Returns:
            Tensor: ``Tensor[N, C + 1]``: ``sigmoid`` of each class, then
            ``prod_c (1 - p_c)`` (no class present).
        """
        prob = cls_score.sigmoid()
        background = (1 - prob).prod(dim=-1, keepdim=True)
        return torch.cat([prob, background], dim=-1)

    def get_accuracy(self, cls_score: Tensor,
                     labels: Tensor) -> Dict[str, Tensor]:
        """Top-1 accuracy over the ``C + 1`` activated columns.

        Args:
            cls_score (Tensor): Logits ``Tensor[N, C]``.
            labels (Tensor): ``Tensor[N]`` in ``[0, C]`` (``C`` background).

        Returns:
            dict[str, Tensor]: ``acc`` in percent.
        """
        return dict(acc=accuracy(self.get_activation(cls_score), labels))
