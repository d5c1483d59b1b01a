# parts set, second table: the demo CBNet on SegFormer's MiT-B0 (GELU,
# overlapping patch embedding) instead of Mish and CSPE.
_base_ = [
    '../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
    './_base_/parts.py',
]
model = dict(backbone=dict(**_base_.stock_trunk))
