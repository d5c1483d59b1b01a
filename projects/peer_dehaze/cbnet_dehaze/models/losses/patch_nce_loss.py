"""Patch-wise contrastive loss (PatchNCE, Park et al. ECCV 2020)."""
import torch
import torch.nn.functional as F
from mmdet.registry import MODELS
from torch import Tensor, nn


def patch_nce(query: Tensor, key: Tensor, tau: float = 0.07) -> Tensor:
    """InfoNCE between corresponding patches of two images.

    For every image, the query patch ``i`` (from the output image) must
    pick its own key patch ``i`` (from the input image at the same place)
    among all ``N`` key patches of that image (the other ``N - 1`` are the
    negatives): cross-entropy of ``softmax(q_i . k_j / tau)`` over ``j``
    with target ``i``, on L2-normalised features.

    Args:
        query (Tensor[B, N, D]): output-image patch features.
        key (Tensor[B, N, D]): input-image patch features (detached by the
            caller if no gradient should reach the encoder through them).
        tau (float): temperature. Defaults to 0.07 (CUT).

    Returns:
        Tensor: scalar, mean over the B * N patches.
    """
    if query.shape != key.shape or query.dim() != 3:
        raise ValueError(f'patch_nce: expected two Tensor[B, N, D] of one '
                         f'shape, got {tuple(query.shape)} and '
                         f'{tuple(key.shape)}')
    b, n, _ = query.shape
    if b * n == 0:
        return query.sum() * 0
    q = F.normalize(query, dim=-1)
    k = F.normalize(key, dim=-1)
    logits = torch.bmm(q, k.transpose(1, 2)) / tau  # [B, N, N]
    target = torch.arange(n, device=q.device).repeat(b)
    return F.cross_entropy(logits.reshape(b * n, n), target)


@MODELS.register_module()
class CBNetPatchNCELoss(nn.Module):
    """PatchNCE over several feature layers with MLP projection heads.

    Samples the same ``num_patches`` random locations in the feature maps
    of the input and of the output image, projects each location's
    feature with a 2-layer MLP per layer (as CUT does) and averages
    :func:`patch_nce` over the layers.

    Args:
        in_channels (list[int]): Channels of each feature layer.
        num_patches (int): Locations sampled per image. Defaults to 256.
        proj_channels (int): MLP output width. Defaults to 64.
        tau (float): Temperature. Defaults to 0.07.
        loss_weight (float): Weight. Defaults to 1.
    """

    def __init__(self,
                 in_channels,
                 num_patches: int = 256,
                 proj_channels: int = 64,
                 tau: float = 0.07,
                 loss_weight: float = 1.0) -> None:
        super().__init__()
        self.num_patches = num_patches
        self.tau = tau
        self.loss_weight = loss_weight
        self.heads = nn.ModuleList(
            nn.Sequential(
                nn.Linear(c, proj_channels), nn.ReLU(inplace=True),
                nn.Linear(proj_channels, proj_channels))
            for c in in_channels)

    def forward(self, feats_out, feats_in) -> Tensor:
        """Loss between the output's and the input's features.

        Args:
            feats_out (list[Tensor[B, C_l, H_l, W_l]]): features of the
                dehazed image (queries).
            feats_in (list[Tensor[B, C_l, H_l, W_l]]): features of the hazy
                input (keys), same shapes.

        Returns:
            Tensor: scalar loss.
        """
        if len(feats_out) != len(self.heads) or len(feats_in) != len(
                self.heads):
            raise ValueError(f'CBNetPatchNCELoss: expected {len(self.heads)}'
                             f' feature layers, got {len(feats_out)} and '
                             f'{len(feats_in)}')
        total = 0
        for head, f_out, f_in in zip(self.heads, feats_out, feats_in):
            b, c, h, w = f_out.shape
            n = min(self.num_patches, h * w)
            idx = torch.randperm(h * w, device=f_out.device)[:n]
            q = head(f_out.flatten(2)[:, :, idx].transpose(1, 2))
            k = head(f_in.flatten(2)[:, :, idx].transpose(1, 2))
            total = total + patch_nce(q, k, self.tau)
        return self.loss_weight * total / len(self.heads)
