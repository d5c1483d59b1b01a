"""Contextual-spatial position encoding (CSPE), formula (1) of the paper.

Our reading of formula (1) (docs/design_readings.md) adds a contextual
relative position term, in the "product" form of iRPE (Wu et al., ICCV
2021), to the attention logits of every MiT block::

    e_ij = (x_i W^Q)(x_j W^K)^T / sqrt(d) + (x_i W^Q) r_ij^T / sqrt(d)

``r_ij`` is a learnable ``d``-vector (one table per attention head) looked
up by the bucketed 2-D offset between query ``i`` and key ``j``.

Offsets. MiT's keys come from a spatially-reduced grid: a ``sr x sr``
convolution with stride ``sr`` maps the ``Hq x Wq`` query (token) grid to
``Hk x Wk = floor(Hq / sr) x floor(Wq / sr)``. Key ``j = (jy, jx)``
summarises query cells ``jy*sr .. jy*sr + sr - 1`` (rows, likewise
columns), so its centre lies at ``jy*sr + (sr - 1) / 2`` on the query grid.
The offset of query ``iy`` from key ``jy`` is therefore::

    dy = iy - jy * sr - (sr - 1) / 2

in units of query tokens, i.e. of the stage's pixel grid (one unit is
``stride`` input pixels: 4, 8, 16, 32 for the four stages). Offsets are
half-integers when ``sr`` is even. ``dx`` is defined the same way.

Bucketing (per axis, piecewise like iRPE). With ``a = |d|``::

    g(a) = floor(a + 1/2)                                   if a <= alpha
    g(a) = min(beta, floor(alpha + ln(a / alpha) / ln(gamma / alpha)
                           * (beta - alpha) + 1/2))           otherwise
    bucket(d) = sign(d) * g(|d|)        in [-beta, beta]

so offsets up to ``alpha`` tokens keep their own bucket (rounded half away
from zero, which keeps the buckets symmetric for half-integer offsets),
farther ones share logarithmically wider buckets, and everything beyond
``gamma`` tokens shares the outermost bucket. The 2-D bucket is the pair
``(bucket(dy), bucket(dx))``: ``(2 beta + 1) ** 2`` entries per head. No
table depends on the input size, so any input size (odd sizes, padded
batches) works; the index grids are recomputed from the actual query and
key grid shapes on every call (they cost ``O(Hq*Hk + Wq*Wk)``).
"""
import math
from typing import Tuple

import torch
import torch.nn as nn
from mmdet.utils import OptMultiConfig
from mmengine.model import BaseModule
from torch import Tensor


def relative_offsets(num_queries: int,
                     sr_ratio: int,
                     num_keys: int,
                     device=None) -> Tensor:
    """Offsets along one axis between the query grid and reduced key grid.

    Args:
        num_queries (int): Query grid length along the axis (tokens).
        sr_ratio (int): Spatial-reduction ratio (kernel = stride of the
            reduction convolution).
        num_keys (int): Key grid length along the axis, normally
            ``num_queries // sr_ratio``.
        device (torch.device, optional): Device of the result.

    Returns:
        Tensor[num_queries, num_keys]: ``q - (k * sr + (sr - 1) / 2)`` in
        query-token units (float32).
    """
    q = torch.arange(num_queries, device=device, dtype=torch.float32)
    k = torch.arange(num_keys, device=device, dtype=torch.float32)
    k = k * sr_ratio + (sr_ratio - 1) / 2
    return q[:, None] - k[None, :]


def piecewise_bucket(offsets: Tensor, alpha: float, beta: int,
                     gamma: float) -> Tensor:
    """Signed piecewise (exact near, logarithmic far) bucket of offsets.

    Args:
        offsets (Tensor): Offsets in tokens, any shape, floating point.
        alpha (float): Offsets with ``|d| <= alpha`` get exact buckets.
        beta (int): Largest bucket magnitude; buckets are in
            ``[-beta, beta]``.
        gamma (float): Offsets with ``|d| >= gamma`` share bucket
            ``+-beta``.

    Returns:
        Tensor: Integer buckets (int64) of the shape of ``offsets``.
    """
    mag = offsets.abs()
    near = torch.floor(mag + 0.5)
    # clamp keeps log() finite on the (unused) near branch
    far = alpha + torch.log(mag.clamp(min=alpha) / alpha) / math.log(
        gamma / alpha) * (beta - alpha)
    far = torch.floor(far + 0.5).clamp(max=beta)
    bucket = torch.where(mag <= alpha, near, far)
    return (torch.sign(offsets) * bucket).long()


class ContextualPositionEncoding(BaseModule):
    """Bucketed contextual relative-position term of the attention logits.

    See the module docstring for the offsets and the bucketing. The table
    is zero-initialised, so a model loaded from an OPE (SegFormer)
    checkpoint starts out computing exactly the pretrained function, and
    the term is learnt from there (its gradient is ``q`` times the softmax
    gradient, non-zero even at zero).

    Args:
        num_heads (int): Attention heads.
        head_dims (int): Channels per head ``d``.
        alpha (float): Exact-bucket range in tokens. Defaults to 3.
        beta (int): Buckets per axis are ``2 * beta + 1``. Defaults to 7.
        gamma (float): Offset (tokens) from which all share the outermost
            bucket. Defaults to 32.
        init_cfg (dict or list[dict], optional): Initialization config.
    """

    def __init__(self,
                 num_heads: int,
                 head_dims: int,
                 alpha: float = 3.,
                 beta: int = 7,
                 gamma: float = 32.,
                 init_cfg: OptMultiConfig = None) -> None:
        super().__init__(init_cfg=init_cfg)
        if not (0 < alpha <= beta < gamma) or int(beta) != beta:
            raise ValueError('CSPE needs 0 < alpha <= beta < gamma with an '
                             f'integer beta, got alpha={alpha}, '
                             f'beta={beta}, gamma={gamma}')
        self.num_heads = num_heads
        self.head_dims = head_dims
        self.alpha = float(alpha)
        self.beta = int(beta)
        self.gamma = float(gamma)
        self.num_buckets = 2 * self.beta + 1
        #: r of formula (1): Tensor[heads, (2 beta + 1) ** 2, d]
        self.table = nn.Parameter(
            torch.zeros(num_heads, self.num_buckets**2, head_dims))

    def bucket_index(self, q_len: int, k_len: int, sr_ratio: int,
                     device=None) -> Tensor:
        """Buckets shifted to ``[0, 2 beta]`` along one axis.

        Returns:
            Tensor[q_len, k_len]: int64 bucket of each (query, key) pair.
        """
        off = relative_offsets(q_len, sr_ratio, k_len, device=device)
        return piecewise_bucket(off, self.alpha, self.beta,
                                self.gamma) + self.beta

    def forward(self,
                q: Tensor,
                q_shape: Tuple[int, int],
                k_shape: Tuple[int, int],
                sr_ratio: int,
                row_start: int = 0) -> Tensor:
        """Compute ``q_i . r_ij / sqrt(d)`` for every query/key pair.

        Args:
            q (Tensor[B, heads, Hq*Wq, d]): Projected queries ``x W^Q``.
            q_shape (tuple[int, int]): Query grid ``(Hq, Wq)``.
            k_shape (tuple[int, int]): Reduced key grid ``(Hk, Wk)``.
            sr_ratio (int): Spatial-reduction ratio of the keys.
            row_start (int): Row of the whole query grid that ``q``'s first
                row is (``q`` a band of rows of it: the attention's query
                chunks). Defaults to 0.

        Returns:
            Tensor[B, heads, Hq*Wq, Hk*Wk]: Term added to the logits.
        """
        (hq, wq), (hk, wk) = q_shape, k_shape
        batch = q.shape[0]
        nb = self.num_buckets
        # q . r / sqrt(d) for every bucket: [B, h, Hq, Wq, nb_y, nb_x]
        qr = torch.matmul(q * self.head_dims**-0.5,
                          self.table.transpose(-1, -2))
        qr = qr.view(batch, self.num_heads, hq, wq, nb, nb)
        by = self.bucket_index(row_start + hq, hk, sr_ratio,
                               q.device)[row_start:]
        bx = self.bucket_index(wq, wk, sr_ratio, q.device)
        if self.num_heads > 1:
            # one gather over the flattened 2-D bucket with an [N, M]
            # index (as large as one head's output), shared by the heads:
            # MiT-B5 stage 3 at 512x1024 (5 heads), 24 -> 15 ms a block
            index = (by.view(hq, 1, hk, 1) * nb +
                     bx.view(1, wq, 1, wk)).view(1, 1, hq * wq, hk * wk)
            return qr.view(batch, self.num_heads, hq * wq, nb * nb).gather(
                3, index.expand(batch, self.num_heads, -1, -1))
        # one head: two gathers with broadcast (stride-0) indices, as the
        # y bucket depends on (iy, jy) only and the x bucket on (ix, jx)
        # only, so no [N, M] index is materialised (stage 1 of MiT at
        # 512x1024: 128 ms, against 190 ms with the index)
        bias = qr.gather(
            4,
            by.view(1, 1, hq, 1, hk, 1).expand(batch, self.num_heads, hq, wq,
                                               hk, nb))
        bias = bias.gather(
            5,
            bx.view(1, 1, 1, wq, 1, wk).expand(batch, self.num_heads, hq, wq,
                                               hk, wk))
        return bias.reshape(batch, self.num_heads, hq * wq, hk * wk)

    def extra_repr(self) -> str:
        return (f'heads={self.num_heads}, head_dims={self.head_dims}, '
                f'alpha={self.alpha}, beta={self.beta}, gamma={self.gamma}')
