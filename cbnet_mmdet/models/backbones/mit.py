"""CBNet's Mix Vision Transformer (MiT) backbone, paper section II.A."""
import math
from typing import Dict, List, Optional, Sequence, Tuple, Union

import torch
import torch.nn as nn
from mmcv.cnn import build_norm_layer
from mmdet.models.layers import PatchEmbed, nlc_to_nchw
from mmdet.registry import MODELS
from mmdet.utils import ConfigType, OptConfigType, OptMultiConfig
from mmengine.logging import MMLogger
from mmengine.model import (BaseModule, ModuleList, constant_init,
                            normal_init, trunc_normal_init)
from mmengine.runner.checkpoint import CheckpointLoader, load_state_dict
from torch import Tensor
from torch.nn.modules.batchnorm import _BatchNorm

from ..layers import CBNetMish  # noqa: F401  (registers 'CBNetMish')
from ..utils import RefuseMisfitMixin
from .mit_checkpoint import convert_mit_checkpoint
from .mit_layers import MiTEncoderLayer


@MODELS.register_module()
class CBNetMiT(RefuseMisfitMixin, BaseModule):
    """Mix Vision Transformer with Mish and CSPE (CBNet, section II.A).

    SegFormer's MiT encoder (Xie et al., 2021): four stages, each an
    overlapping patch embedding (conv 7x7/4, then 3x3/2), ``depths[i]``
    blocks of spatial-reduction attention + Mix-FFN (1x1 conv, 3x3
    depth-wise conv, activation, 1x1 conv), and a LayerNorm. CBNet's
    changes: the FFN activation is Mish by default, and with
    ``pos_encoding='cspe'`` every attention adds the contextual relative
    position term of formula (1) (see :mod:`.cspe`). The overlapping patch
    embedding (the downsampling itself) is kept in both modes, so ``'ope'``
    is exactly SegFormer/mmsegmentation's MiT and ``'cspe'`` is that plus
    the CSPE term (zero at initialisation).

    Parameter names follow mmsegmentation's ``MixVisionTransformer``.
    ``init_cfg=dict(type='Pretrained', checkpoint=...)`` also reads the
    official SegFormer ``mit_b*.pth`` layout; keys not loaded are logged
    (missing: the CSPE tables; unexpected; ignored: the ImageNet head).

    Args:
        arch (str | dict): ``'b0'`` ... ``'b5'``, or a dict with
            ``embed_dims``, ``depths``, ``num_heads``, ``sr_ratios`` (one
            entry per stage) and optionally ``mlp_ratios``,
            ``patch_sizes``, ``strides``. Defaults to ``'b0'``.
        in_channels (int): Input image channels. Defaults to 3.
        out_indices (Sequence[int]): Stages whose outputs are returned.
            Defaults to ``(0, 1, 2, 3)``.
        qkv_bias (bool): Bias of the q/k/v projections. Defaults to True.
        drop_rate (float): Dropout rate. Defaults to 0.
        attn_drop_rate (float): Attention-weight dropout. Defaults to 0.
        drop_path_rate (float): Stochastic depth, rising linearly over all
            blocks to this value. Defaults to 0.1.
        act_cfg (dict): FFN activation. Defaults to
            ``dict(type='CBNetMish')``, the paper's Mish with a faster CPU
            kernel (``dict(type=torch.nn.Mish)`` is torch's, the same
            function); ``dict(type='GELU')`` is SegFormer's.
        norm_cfg (dict): Token normalisation. Defaults to
            ``dict(type='LN', eps=1e-6)``.
        pos_encoding (str): ``'cspe'`` (default) or ``'ope'``.
        cspe_cfg (dict, optional): ``alpha``, ``beta``, ``gamma`` of the
            CSPE bucketing. Defaults to ``dict(alpha=3, beta=7, gamma=32)``:
            per axis, the offset between a query token and the centre of a
            spatially-reduced key (in the stage's token units, i.e.
            ``stride`` pixels) keeps its own bucket up to 3 tokens, shares
            log-spaced buckets up to 32 tokens, and the outermost bucket
            beyond; 15 x 15 buckets per head, any input size.
        attn_query_chunk (int, optional): With CSPE, every attention
            attends at most this many query tokens at a time (whole rows),
            so the CSPE term and the logits are held for one band of
            queries instead of all of them (stage 1 at 1024x2048: 1 GiB a
            head and image in full); the same result. ``None`` (default,
            the paper's formula computed at once) attends all queries
            together.
        frozen_stages (int): The first ``frozen_stages`` stages (patch
            embedding, blocks and norm) are frozen and kept in eval mode;
            -1 or 0 freezes nothing. Defaults to -1.
        norm_eval (bool): Keep ``_BatchNorm`` layers in eval mode during
            training (MMDet convention; the default LayerNorms have no
            running statistics). Defaults to False.
        init_cfg (dict or list[dict], optional): Initialization config;
            ``dict(type='Pretrained', checkpoint=PATH)`` loads MiT weights.

    Attributes:
        embed_dims (list[int]): Channels of all four stages.
        out_channels (list[int]): Channels of the returned maps.
        out_strides (list[int]): Strides (pixels) of the returned maps.
    """

    arch_settings: Dict[str, Dict[str, List[int]]] = {
        'b0': dict(embed_dims=[32, 64, 160, 256], depths=[2, 2, 2, 2]),
        'b1': dict(embed_dims=[64, 128, 320, 512], depths=[2, 2, 2, 2]),
        'b2': dict(embed_dims=[64, 128, 320, 512], depths=[3, 4, 6, 3]),
        'b3': dict(embed_dims=[64, 128, 320, 512], depths=[3, 4, 18, 3]),
        'b4': dict(embed_dims=[64, 128, 320, 512], depths=[3, 8, 27, 3]),
        'b5': dict(embed_dims=[64, 128, 320, 512], depths=[3, 6, 40, 3]),
    }
    #: Shared by all published sizes.
    common_settings: Dict[str, List[int]] = dict(
        num_heads=[1, 2, 5, 8],
        sr_ratios=[8, 4, 2, 1],
        mlp_ratios=[4, 4, 4, 4],
        patch_sizes=[7, 3, 3, 3],
        strides=[4, 2, 2, 2])
    _required = ('embed_dims', 'depths', 'num_heads', 'sr_ratios')
    #: Tensors a checkpoint may lack (RefuseMisfitMixin): the CSPE tables,
    #: which the published SegFormer weights have none of; they keep their
    #: zero initialisation. Any other tensor missing or of another shape (a
    #: MiT of another size, another trunk) is refused, whoever loads it.
    misfit_optional = ('cspe.table', )

    def __init__(self,
                 arch: Union[str, dict] = 'b0',
                 in_channels: int = 3,
                 out_indices: Sequence[int] = (0, 1, 2, 3),
                 qkv_bias: bool = True,
                 drop_rate: float = 0.,
                 attn_drop_rate: float = 0.,
                 drop_path_rate: float = 0.1,
                 act_cfg: ConfigType = dict(type='CBNetMish'),
                 norm_cfg: ConfigType = dict(type='LN', eps=1e-6),
                 pos_encoding: str = 'cspe',
                 cspe_cfg: OptConfigType = None,
                 attn_query_chunk: Optional[int] = None,
                 frozen_stages: int = -1,
                 norm_eval: bool = False,
                 init_cfg: OptMultiConfig = None) -> None:
        super().__init__(init_cfg=init_cfg)
        arch = self._parse_arch(arch)
        num_stages = len(arch['depths'])
        if pos_encoding not in ('cspe', 'ope'):
            raise ValueError("pos_encoding must be 'cspe' or 'ope', got "
                             f'{pos_encoding!r}')
        out_indices = tuple(out_indices)
        if not out_indices or any(not 0 <= i < num_stages
                                  for i in out_indices):
            raise ValueError(f'out_indices must be a non-empty subset of '
                             f'0..{num_stages - 1}, got {out_indices}')
        if not -1 <= frozen_stages <= num_stages:
            raise ValueError(f'frozen_stages must be in [-1, {num_stages}]'
                             f', got {frozen_stages}')
        if pos_encoding == 'cspe':
            cspe_cfg = {**dict(alpha=3, beta=7, gamma=32), **(cspe_cfg or {})}
        else:
            cspe_cfg = None
        self.arch = arch
        self.pos_encoding = pos_encoding
        self.out_indices = out_indices
        self.frozen_stages = frozen_stages
        self.norm_eval = norm_eval
        self.embed_dims = list(arch['embed_dims'])
        self.out_channels = [self.embed_dims[i] for i in out_indices]
        strides = [
            math.prod(arch['strides'][:i + 1]) for i in range(num_stages)
        ]
        self.out_strides = [strides[i] for i in out_indices]

        total = sum(arch['depths'])
        # cpu: also under ``with torch.device('meta')``
        dpr = torch.linspace(0, drop_path_rate, total, device='cpu').tolist()
        self.layers = ModuleList()
        start = 0
        for i in range(num_stages):
            dims = arch['embed_dims'][i]
            patch_embed = PatchEmbed(
                in_channels=in_channels,
                embed_dims=dims,
                kernel_size=arch['patch_sizes'][i],
                stride=arch['strides'][i],
                padding=arch['patch_sizes'][i] // 2,
                bias=True,
                norm_cfg=norm_cfg)
            blocks = ModuleList([
                MiTEncoderLayer(
                    embed_dims=dims,
                    num_heads=arch['num_heads'][i],
                    feedforward_channels=arch['mlp_ratios'][i] * dims,
                    sr_ratio=arch['sr_ratios'][i],
                    drop_rate=drop_rate,
                    attn_drop_rate=attn_drop_rate,
                    drop_path_rate=dpr[start + j],
                    qkv_bias=qkv_bias,
                    act_cfg=act_cfg,
                    norm_cfg=norm_cfg,
                    cspe_cfg=cspe_cfg,
                    query_chunk=attn_query_chunk)
                for j in range(arch['depths'][i])
            ])
            norm = build_norm_layer(norm_cfg, dims)[1]
            self.layers.append(ModuleList([patch_embed, blocks, norm]))
            in_channels = dims
            start += arch['depths'][i]
        self._freeze_stages()

    @classmethod
    def _parse_arch(cls, arch: Union[str, dict]) -> Dict[str, List[int]]:
        """Full per-stage settings from a name or a dict; checks them."""
        if isinstance(arch, str):
            name = arch.lower()
            if name not in cls.arch_settings:
                raise ValueError(
                    f'CBNetMiT: unknown arch {arch!r}; valid names are '
                    f'{sorted(cls.arch_settings)} or a dict with keys '
                    f'{list(cls._required)}')
            return {**cls.common_settings, **cls.arch_settings[name]}
        if not isinstance(arch, dict):
            raise TypeError('CBNetMiT: arch must be a str or a dict, got '
                            f'{type(arch).__name__}')
        missing = [k for k in cls._required if k not in arch]
        unknown = [
            k for k in arch
            if k not in cls._required and k not in cls.common_settings
        ]
        if missing or unknown:
            raise ValueError(f'CBNetMiT: arch dict is missing keys {missing}'
                             f' / has unknown keys {unknown}')
        arch = {**cls.common_settings, **{k: list(v) for k, v in arch.items()}}
        lengths = {k: len(v) for k, v in arch.items()}
        if len(set(lengths.values())) != 1:
            raise ValueError('CBNetMiT: arch entries need one value per '
                             f'stage, got lengths {lengths}')
        for dims, heads in zip(arch['embed_dims'], arch['num_heads']):
            if dims % heads:
                raise ValueError(f'CBNetMiT: embed_dims {dims} is not '
                                 f'divisible by num_heads {heads}')
        return arch

    def _freeze_stages(self) -> None:
        """Freeze the first ``frozen_stages`` stages (eval, no grad)."""
        for stage in self.layers[:max(self.frozen_stages, 0)]:
            stage.eval()
            for param in stage.parameters():
                param.requires_grad = False

    def train(self, mode: bool = True) -> 'CBNetMiT':
        """Set train mode, keeping frozen stages (and BN) in eval mode."""
        super().train(mode)
        self._freeze_stages()
        if mode and self.norm_eval:
            for m in self.modules():
                if isinstance(m, _BatchNorm):
                    m.eval()
        return self

    def init_weights(self) -> None:
        """Load a MiT checkpoint or initialise like SegFormer.

        With ``init_cfg=dict(type='Pretrained', checkpoint=PATH)`` the
        checkpoint (official SegFormer or mmsegmentation layout, see
        :func:`convert_mit_checkpoint`) is loaded non-strictly; ignored,
        missing ``attn.cspe.table`` and unexpected keys are logged as
        warnings by MMLogger; any other missing tensor, or one of another
        shape (a MiT of another size), is a ``CheckpointMismatchError``.
        Without ``init_cfg``: truncated-normal linear layers, fan-out
        normal convolutions, unit norms, zero CSPE tables. Any other
        ``init_cfg`` goes to ``BaseModule``.
        """
        logger = MMLogger.get_current_instance()
        cfg = self.init_cfg
        if isinstance(cfg, dict) and cfg.get('type') == 'Pretrained':
            if 'checkpoint' not in cfg:
                raise KeyError("CBNetMiT: init_cfg of type 'Pretrained' "
                               "needs a 'checkpoint' path")
            ckpt = CheckpointLoader.load_checkpoint(
                cfg['checkpoint'], map_location='cpu', logger=logger)
            state_dict, ignored, layout = convert_mit_checkpoint(ckpt)
            logger.info(f'CBNetMiT: loading {layout}-layout MiT weights '
                        f'from {cfg["checkpoint"]}')
            if ignored:
                logger.warning('CBNetMiT: ignored checkpoint keys that are '
                               'not backbone parameters: ' +
                               ', '.join(ignored))
            load_state_dict(self, state_dict, strict=False, logger=logger)
            self._is_init = True
        elif cfg is None:
            for m in self.modules():
                if isinstance(m, nn.Linear):
                    trunc_normal_init(m, std=.02, bias=0.)
                elif isinstance(m, nn.LayerNorm):
                    constant_init(m, 1.0)
                elif isinstance(m, nn.Conv2d):
                    fan_out = m.kernel_size[0] * m.kernel_size[1] * \
                        m.out_channels // m.groups
                    normal_init(m, 0, math.sqrt(2.0 / fan_out))
            self._is_init = True
        else:
            super().init_weights()

    def forward(self, x: Tensor) -> Tuple[Tensor, ...]:
        """Extract the multi-scale features.

        Args:
            x (Tensor[B, C_in, H, W]): Images; ``H, W >= 29`` pixels.

        Returns:
            tuple[Tensor]: For each of ``out_indices``, a map
            ``Tensor[B, out_channels[k], ceil(H / s), ceil(W / s)]`` with
            stride ``s = out_strides[k]`` (4, 8, 16, 32).
        """
        if x.dim() != 4:
            raise ValueError('CBNetMiT expects images Tensor[B, C, H, W], '
                             f'got shape {tuple(x.shape)}')
        if x.shape[0] == 0:  # torch's attention cannot reshape empty batches
            return self._empty_outputs(x)
        outs = []
        for i, (patch_embed, blocks, norm) in enumerate(self.layers):
            x, hw_shape = patch_embed(x)
            for block in blocks:
                x = block(x, hw_shape)
            x = nlc_to_nchw(norm(x), hw_shape)
            if i in self.out_indices:
                outs.append(x)
            if i >= max(self.out_indices):
                break
        return tuple(outs)

    def _empty_outputs(self, x: Tensor) -> Tuple[Tensor, ...]:
        """Zero-batch outputs with the shapes a real forward would give."""
        height, width = x.shape[2:]
        outs = []
        for i, (patch_embed, _, _) in enumerate(self.layers):
            conv = patch_embed.projection
            (kh, kw), (sh, sw), (ph, pw) = (conv.kernel_size, conv.stride,
                                            conv.padding)
            height = (height + 2 * ph - kh) // sh + 1
            width = (width + 2 * pw - kw) // sw + 1
            if i in self.out_indices:
                outs.append(
                    x.new_zeros((0, self.embed_dims[i], height, width)))
        return tuple(outs)
