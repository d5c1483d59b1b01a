"""Building blocks of :class:`CBNetMiT`: attention and encoder layer.

Both reuse MMDetection's PVTv2 pieces (``SpatialReductionAttention`` and
``MixFFN`` from ``mmdet.models.backbones.pvt``), which are the SegFormer
MiT blocks with mmsegmentation's parameter layout. We add the optional
CSPE term (:mod:`.cspe`) to the attention logits, and run Mix-FFN on the
token layout (:class:`TokenMixFFN`).
"""
from typing import Optional, Tuple

import torch
import torch.nn.functional as F
from mmcv.cnn import build_norm_layer
from mmdet.models.backbones.pvt import MixFFN, SpatialReductionAttention
from mmdet.models.layers import nchw_to_nlc, nlc_to_nchw
from mmdet.registry import MODELS
from mmdet.utils import ConfigType, OptConfigType, OptMultiConfig
from mmengine.model import BaseModule
from torch import Tensor

from .cspe import ContextualPositionEncoding


class CSPESpatialReductionAttention(SpatialReductionAttention):
    """Spatial-reduction attention with an optional CSPE logit term.

    With ``cspe_cfg=None`` this is exactly MMDetection's (and
    mmsegmentation's) MiT attention. Otherwise the term
    ``q_i . r_ij / sqrt(d)`` of formula (1) is added to the logits: the
    projections are computed once from the ``nn.MultiheadAttention``'s own
    ``in_proj_weight`` / ``out_proj`` (so the parameter layout stays that of
    the pretrained checkpoints), the CSPE term from the projected queries,
    and ``F.scaled_dot_product_attention`` attends with it as a float mask.
    This is ``nn.MultiheadAttention(..., attn_mask=term)`` without its
    second query projection (one ``N x C x C`` matmul per block).

    Args:
        embed_dims (int): Channels ``C``.
        num_heads (int): Attention heads.
        sr_ratio (int): Spatial-reduction ratio of keys/values.
        cspe_cfg (dict, optional): ``alpha``/``beta``/``gamma`` of
            :class:`ContextualPositionEncoding`; ``None`` disables CSPE.
        query_chunk (int, optional): With CSPE, attend at most this many
            query tokens at a time (whole rows of the grid, at least one),
            so that the CSPE term and the logits exist for one band of
            queries at a time instead of all ``H*W x h*w`` pairs (1 GiB a
            head for stage 1 at 1024x2048). The same result; ``None``
            (default) attends all queries at once.
        **kwargs: Remaining arguments of ``SpatialReductionAttention``.
    """

    def __init__(self,
                 embed_dims: int,
                 num_heads: int,
                 sr_ratio: int = 1,
                 cspe_cfg: OptConfigType = None,
                 query_chunk: Optional[int] = None,
                 **kwargs) -> None:
        super().__init__(
            embed_dims, num_heads, sr_ratio=sr_ratio, **kwargs)
        if query_chunk is not None and (int(query_chunk) != query_chunk
                                        or query_chunk < 1):
            raise ValueError('query_chunk must be a positive integer or '
                             f'None, got {query_chunk!r}')
        self.query_chunk = query_chunk
        self.cspe = None
        if cspe_cfg is not None:
            self.cspe = ContextualPositionEncoding(
                num_heads, embed_dims // num_heads, **cspe_cfg)

    def forward(self,
                x: Tensor,
                hw_shape: Tuple[int, int],
                identity: Optional[Tensor] = None) -> Tensor:
        """Attend from the token grid to its spatially-reduced copy.

        Args:
            x (Tensor[B, H*W, C]): Normalised tokens.
            hw_shape (tuple[int, int]): Token grid ``(H, W)``.
            identity (Tensor[B, H*W, C], optional): Residual; ``x`` if None.

        Returns:
            Tensor[B, H*W, C]: ``identity + attention(x)``.
        """
        if self.sr_ratio > 1 and min(hw_shape) < self.sr_ratio:
            raise ValueError(
                f'CBNetMiT: token grid {tuple(hw_shape)} is smaller than the '
                f'spatial-reduction ratio {self.sr_ratio}; the input image '
                'must be at least 29x29 pixels')
        if self.cspe is None:
            return super().forward(x, hw_shape, identity)
        if identity is None:
            identity = x
        if self.sr_ratio > 1:
            x_kv = self.sr(nlc_to_nchw(x, hw_shape))
            kv_shape = tuple(x_kv.shape[2:])
            x_kv = self.norm(nchw_to_nlc(x_kv))
        else:
            x_kv, kv_shape = x, tuple(hw_shape)
        batch, num_q, channels = x.shape
        heads, num_k = self.num_heads, x_kv.shape[1]
        mha = self.attn
        weight, bias = mha.in_proj_weight, mha.in_proj_bias
        q = F.linear(x, weight[:channels],
                     None if bias is None else bias[:channels])
        kv = F.linear(x_kv, weight[channels:],
                      None if bias is None else bias[channels:])
        # [B, N, C] -> [B, heads, N, d]
        q = q.view(batch, num_q, heads, -1).transpose(1, 2)
        k, v = kv.view(batch, num_k, 2, heads, -1).permute(2, 0, 3, 1, 4)
        height, width = hw_shape
        rows = height if self.query_chunk is None else max(
            1, self.query_chunk // width)
        dropout = mha.dropout if self.training else 0.
        out = []
        for top in range(0, height, rows):  # one band of query rows
            band = q[:, :, top * width:min(top + rows, height) * width]
            pos = self.cspe(band, (band.shape[2] // width, width), kv_shape,
                            self.sr_ratio, row_start=top)
            out.append(F.scaled_dot_product_attention(
                band, k, v, attn_mask=pos, dropout_p=dropout))
        out = out[0] if len(out) == 1 else torch.cat(out, 2)
        out = out.transpose(1, 2).reshape(batch, num_q, channels)
        out = mha.out_proj(out)
        return identity + self.dropout_layer(self.proj_drop(out))


class TokenMixFFN(MixFFN):
    """MMDetection's Mix-FFN (``use_conv=True``) computed on the tokens.

    Same parameters (``layers.0`` 1x1 fc1, ``layers.1`` 3x3 depth-wise
    conv, ``layers.4`` 1x1 fc2) and the same function as ``MixFFN``, but
    the two 1x1 convolutions run as matrix products on the ``[B, H*W, C]``
    tokens, and the depth-wise convolution on a ``channels_last`` view of
    them, so no ``NLC <-> NCHW`` copy is made (``MixFFN`` copies twice per
    block, and PyTorch's CPU 1x1 convolution of an NCHW tensor takes its
    slow im2col path with one thread). Measured on MiT-B5, one CPU thread:
    inference at 512x1024 6.02 -> 5.60 s, forward + backward at 256x512
    3.24 -> 3.13 s.
    """

    def forward(self,
                x: Tensor,
                hw_shape: Tuple[int, int],
                identity: Optional[Tensor] = None) -> Tensor:
        """Args: x (Tensor[B, H*W, C]); hw_shape ``(H, W)``; identity
        (Tensor[B, H*W, C], optional), ``x`` if None.

        Returns:
            Tensor[B, H*W, C]: ``identity + FFN(x)``.
        """
        fc1, dw_conv, act, drop, fc2, _ = self.layers
        batch, num, _ = x.shape
        out = F.linear(x, fc1.weight.flatten(1), fc1.bias)
        hidden = out.shape[-1]
        # [B, H*W, C'] is [B, H, W, C']: an NCHW view in channels_last
        out = out.view(batch, *hw_shape, hidden).permute(0, 3, 1, 2)
        out = drop(act(dw_conv(out)))
        out = out.permute(0, 2, 3, 1).reshape(batch, num, hidden)
        out = drop(F.linear(out, fc2.weight.flatten(1), fc2.bias))
        return (x if identity is None else identity) + \
            self.dropout_layer(out)


class MiTEncoderLayer(BaseModule):
    """One MiT block: SR attention then Mix-FFN, each pre-norm residual.

    Parameter names follow mmsegmentation's ``MixVisionTransformer``
    (``norm1``, ``attn.attn.in_proj_weight``, ``attn.sr``, ``attn.norm``,
    ``norm2``, ``ffn.layers.{0,1,4}``), plus ``attn.cspe.table`` with CSPE.

    Args:
        embed_dims (int): Channels ``C``.
        num_heads (int): Attention heads.
        feedforward_channels (int): Hidden channels of Mix-FFN.
        sr_ratio (int): Spatial-reduction ratio.
        drop_rate (float): Dropout after attention and in the FFN.
        attn_drop_rate (float): Dropout on attention weights.
        drop_path_rate (float): Stochastic-depth rate of both branches.
        qkv_bias (bool): Bias of the q/k/v projections.
        act_cfg (dict): FFN activation (e.g. ``dict(type='CBNetMish')``).
        norm_cfg (dict): Token normalisation layer.
        cspe_cfg (dict, optional): CSPE settings; ``None`` disables it.
        query_chunk (int, optional): See
            :class:`CSPESpatialReductionAttention`.
        init_cfg (dict or list[dict], optional): Initialization config.
    """

    def __init__(self,
                 embed_dims: int,
                 num_heads: int,
                 feedforward_channels: int,
                 sr_ratio: int = 1,
                 drop_rate: float = 0.,
                 attn_drop_rate: float = 0.,
                 drop_path_rate: float = 0.,
                 qkv_bias: bool = True,
                 act_cfg: ConfigType = dict(type='CBNetMish'),
                 norm_cfg: ConfigType = dict(type='LN', eps=1e-6),
                 cspe_cfg: OptConfigType = None,
                 query_chunk: Optional[int] = None,
                 init_cfg: OptMultiConfig = None) -> None:
        super().__init__(init_cfg=init_cfg)
        drop_path = dict(type='DropPath', drop_prob=drop_path_rate)
        self.norm1 = build_norm_layer(norm_cfg, embed_dims)[1]
        self.attn = CSPESpatialReductionAttention(
            embed_dims=embed_dims,
            num_heads=num_heads,
            attn_drop=attn_drop_rate,
            proj_drop=drop_rate,
            dropout_layer=drop_path,
            qkv_bias=qkv_bias,
            norm_cfg=norm_cfg,
            sr_ratio=sr_ratio,
            cspe_cfg=cspe_cfg,
            query_chunk=query_chunk)
        self.norm2 = build_norm_layer(norm_cfg, embed_dims)[1]
        # mmcv's build_activation_layer looks in MMEngine's root registry
        # only: a name is resolved in MMDetection's (ours, then the root)
        act_cfg = dict(act_cfg)
        if isinstance(act_cfg['type'], str) and MODELS.get(act_cfg['type']):
            act_cfg['type'] = MODELS.get(act_cfg['type'])
        self.ffn = TokenMixFFN(
            embed_dims=embed_dims,
            feedforward_channels=feedforward_channels,
            act_cfg=act_cfg,
            ffn_drop=drop_rate,
            dropout_layer=drop_path,
            use_conv=True)

    def forward(self, x: Tensor, hw_shape: Tuple[int, int]) -> Tensor:
        """Args: x (Tensor[B, H*W, C]); hw_shape ``(H, W)``.

        Returns:
            Tensor[B, H*W, C]: Updated tokens.
        """
        x = self.attn(self.norm1(x), hw_shape, identity=x)
        return self.ffn(self.norm2(x), hw_shape, identity=x)
