"""Train and evaluate a dehazer alone on foggy/clear image pairs."""
from typing import Dict, List, Optional, Union

import torch
import torch.nn.functional as F
from mmdet.registry import MODELS
from mmengine.model import BaseModel
from mmengine.optim import OptimWrapper
from torch import Tensor

#: Channels of one RGB image; a paired input holds two of them.
IMG_CHANNELS = 3

#: The paired data preprocessor for [0, 1] RGB foggy (0-2) + clear (3-5).
PAIRED_UNIT_PREPROCESSOR = dict(
    type='CBNetPairedDataPreprocessor',
    mean=[0.0, 0.0, 0.0],
    std=[255.0, 255.0, 255.0],
    bgr_to_rgb=True)


@MODELS.register_module()
class CBNetDehazeModel(BaseModel):
    """A dehazer with its training objective, for MMEngine's runner.

    Inputs come from ``CBNetPairedFoggyDataset`` +
    ``CBNetLoadPairedImageFromFile``: ``Tensor[B, 6, H, W]``, foggy RGB in
    channels 0-2 and the clear twin in 3-5, scaled to [0, 1] by the
    paired data preprocessor (``mean=0, std=255``).

    Objectives:

    * ``'supervised'`` (paired data): ``L1(G(I), J) + SSIM loss(G(I), J)``
      plus, optionally, a perceptual term: L1 between features of a
      frozen backbone (e.g. an ImageNet ResNet through ``init_cfg``).
    * ``'unpaired'`` (paper III-E2, UCL-Dehaze's recipe without its
      self-contrastive perceptual term, which needs VGG weights): vanilla
      GAN loss against a PatchGAN that sees clear images of *other*
      scenes (the clear batch rolled by one, so no pair is used),
      PatchNCE between the dehazer's features of ``I`` and of ``G(I)``,
      and the identity loss ``L1(G(J), J)``. One optimizer holds the
      dehazer, the discriminator and the PatchNCE heads: each step
      back-propagates the generator loss, clears the discriminator's
      gradients, back-propagates the discriminator loss (on detached
      fakes) and steps once.

    ``predict`` returns the data samples with ``pred_img`` (dehazed),
    ``hazy_img`` and, for paired inputs, ``gt_img`` (clear), each
    ``Tensor[3, h, w]`` RGB in [0, 1] cropped to the unpadded size.

    Args:
        dehazer (dict): Dehazer config.
        objective (str): ``'supervised'`` or ``'unpaired'``.
        loss_l1 (dict): Pixel loss (MMDet's ``L1Loss``).
        loss_ssim (dict, optional): SSIM loss; None to drop it.
        perceptual (dict, optional): ``dict(backbone=..., loss_weight=...,
            mean=..., std=...)``: a frozen MMDet backbone whose outputs are
            compared with L1 (inputs normalised by ``mean``/``std`` on the
            [0, 1] scale; ImageNet's by default).
        discriminator (dict): PatchGAN config (unpaired).
        loss_nce (dict): ``CBNetPatchNCELoss`` config (unpaired; its
            ``in_channels`` are filled from the dehazer's features).
        adv_weight (float): Weight of the GAN terms. Defaults to 1.
        idt_weight (float): Weight of the identity loss. Defaults to 1.
        data_preprocessor (dict): Defaults to the paired preprocessor
            scaling to [0, 1].
    """

    def __init__(self,
                 dehazer: dict,
                 objective: str = 'supervised',
                 loss_l1: dict = dict(type='L1Loss', loss_weight=1.0),
                 loss_ssim: Optional[dict] = dict(
                     type='CBNetSSIMLoss', loss_weight=1.0),
                 perceptual: Optional[dict] = None,
                 discriminator: dict = dict(type='CBNetPatchDiscriminator'),
                 loss_nce: dict = dict(type='CBNetPatchNCELoss'),
                 adv_weight: float = 1.0,
                 idt_weight: float = 1.0,
                 data_preprocessor: dict = PAIRED_UNIT_PREPROCESSOR,
                 init_cfg: Optional[dict] = None) -> None:
        # built from MMDetection's registry, whatever the default scope
        super().__init__(
            data_preprocessor=MODELS.build(data_preprocessor),
            init_cfg=init_cfg)
        if objective not in ('supervised', 'unpaired'):
            raise ValueError(f"CBNetDehazeModel: objective must be "
                             f"'supervised' or 'unpaired', got {objective!r}")
        self.objective = objective
        self.dehazer = MODELS.build(dehazer)
        self.loss_l1 = MODELS.build(loss_l1)
        self.loss_ssim = MODELS.build(loss_ssim) if loss_ssim else None
        self.perceptual = None
        if perceptual:
            perceptual = dict(perceptual)
            self.perceptual = MODELS.build(perceptual.pop('backbone'))
            self.perceptual.requires_grad_(False)
            self.perceptual_weight = perceptual.pop('loss_weight', 1.0)
            mean = perceptual.pop('mean', (0.485, 0.456, 0.406))
            std = perceptual.pop('std', (0.229, 0.224, 0.225))
            self.register_buffer('pmean', torch.tensor(mean).view(1, 3, 1, 1),
                                 False)
            self.register_buffer('pstd', torch.tensor(std).view(1, 3, 1, 1),
                                 False)
        if objective == 'unpaired':
            if not hasattr(self.dehazer, 'features'):
                raise ValueError(
                    f'CBNetDehazeModel: the unpaired objective needs a '
                    f'dehazer with features() for PatchNCE; '
                    f'{type(self.dehazer).__name__} has none')
            with torch.no_grad():
                probe = self.dehazer.features(torch.zeros(1, 3, 8, 8))
            self.discriminator = MODELS.build(discriminator)
            self.loss_nce = MODELS.build(
                dict(loss_nce, in_channels=[f.shape[1] for f in probe]))
            self.adv_weight = adv_weight
            self.idt_weight = idt_weight

    def train(self, mode: bool = True):
        """Training mode; a perceptual backbone stays frozen in eval."""
        super().train(mode)
        if self.perceptual is not None:
            self.perceptual.eval()
        return self

    @staticmethod
    def split(inputs: Tensor):
        """Tensor[B, 6, H, W] -> (foggy, clear); 3 channels -> (x, None)."""
        if inputs.shape[1] == 2 * IMG_CHANNELS:
            return inputs[:, :IMG_CHANNELS], inputs[:, IMG_CHANNELS:]
        return inputs, None

    def perceptual_loss(self, pred: Tensor, target: Tensor) -> Tensor:
        """L1 between the frozen backbone's features of pred and target."""
        norm = lambda x: (x - self.pmean) / self.pstd  # noqa: E731
        feats_p = self.perceptual(norm(pred))
        with torch.no_grad():
            feats_t = self.perceptual(norm(target))
        return self.perceptual_weight * sum(
            F.l1_loss(p, t) for p, t in zip(feats_p, feats_t)) / len(feats_t)

    def supervised_losses(self, foggy: Tensor, clear: Tensor) -> Dict:
        """L1 (+ SSIM, + perceptual) losses of ``G(foggy)`` vs ``clear``."""
        pred = self.dehazer(foggy)
        losses = dict(loss_l1=self.loss_l1(pred, clear))
        if self.loss_ssim is not None:
            losses['loss_ssim'] = self.loss_ssim(pred, clear)
        if self.perceptual is not None:
            losses['loss_perceptual'] = self.perceptual_loss(pred, clear)
        return losses

    def gan_loss(self, img: Tensor, real: bool) -> Tensor:
        """Vanilla GAN loss: BCE of the PatchGAN logits vs real/fake."""
        logits = self.discriminator(img)
        return F.binary_cross_entropy_with_logits(
            logits, torch.full_like(logits, float(real)))

    def unpaired_losses(self, foggy: Tensor, clear: Tensor):
        """Generator losses and the discriminator loss (unpaired).

        Returns:
            tuple[dict, Tensor]: generator losses (``loss_adv``,
            ``loss_nce``, ``loss_idt``) and the discriminator loss.
        """
        if foggy.shape[0] < 2:
            raise ValueError(
                'CBNetDehazeModel: the unpaired objective needs batches of '
                '>= 2 images (clear images of other scenes are the real '
                'samples)')
        other_clear = clear.roll(1, dims=0)
        feats_in = self.dehazer.features(foggy)
        fake = self.dehazer(foggy)
        feats_out = self.dehazer.features(fake)
        g_losses = dict(
            loss_adv=self.adv_weight * self.gan_loss(fake, True),
            loss_nce=self.loss_nce(feats_out, feats_in),
            loss_idt=self.idt_weight *
            F.l1_loss(self.dehazer(other_clear), other_clear))
        d_loss = 0.5 * self.adv_weight * (
            self.gan_loss(other_clear, True) +
            self.gan_loss(fake.detach(), False))
        return g_losses, d_loss

    def train_step(self, data: Union[dict, tuple, list],
                   optim_wrapper: OptimWrapper) -> Dict[str, Tensor]:
        """One optimisation step (see the class docstring)."""
        if self.objective == 'supervised':
            return super().train_step(data, optim_wrapper)
        with optim_wrapper.optim_context(self):
            data = self.data_preprocessor(data, True)
            foggy, clear = self.split(data['inputs'])
            if clear is None:
                raise ValueError('CBNetDehazeModel: training needs paired '
                                 '6-channel foggy+clear inputs')
            g_losses, d_loss = self.unpaired_losses(foggy, clear)
        g_loss, log_vars = self.parse_losses(g_losses)
        optim_wrapper.backward(g_loss)
        for p in self.discriminator.parameters():
            p.grad = None  # the generator step must not train D
        optim_wrapper.backward(d_loss)
        optim_wrapper.step()
        optim_wrapper.zero_grad()
        log_vars['loss_d'] = d_loss.detach()
        return log_vars

    def forward(self,
                inputs: Tensor,
                data_samples: Optional[List] = None,
                mode: str = 'tensor'):
        """``loss`` (supervised), ``predict`` or ``tensor`` (dehazed).

        Args:
            inputs (Tensor[B, 6 or 3, H, W]): [0, 1] RGB, preprocessed.
            data_samples (list, optional): ``DetDataSample`` s with
                ``img_shape`` (the unpadded size).
            mode (str): ``'loss'``, ``'predict'`` or ``'tensor'``.
        """
        foggy, clear = self.split(inputs)
        if mode == 'loss':
            if clear is None:
                raise ValueError('CBNetDehazeModel: training needs paired '
                                 '6-channel foggy+clear inputs')
            if self.objective == 'unpaired':
                return self.unpaired_losses(foggy, clear)[0]
            return self.supervised_losses(foggy, clear)
        pred = self.dehazer(foggy)
        if mode == 'tensor':
            return pred
        if mode != 'predict':
            raise ValueError(f'CBNetDehazeModel: unknown mode {mode!r}')
        for i, sample in enumerate(data_samples):
            h, w = sample.img_shape[:2]
            sample.pred_img = pred[i, :, :h, :w]
            sample.hazy_img = foggy[i, :, :h, :w]
            if clear is not None:
                sample.gt_img = clear[i, :, :h, :w]
        return data_samples
