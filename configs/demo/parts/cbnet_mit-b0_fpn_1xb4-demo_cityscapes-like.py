# parts set, second table: the demo CBNet with MMDet's FPN instead of the
# NAS-FPN neck (everything else CBNet's).
_base_ = [
    '../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
    './_base_/parts.py',
]
model = dict(
    data_preprocessor=dict(pad_size_divisor=_base_.stock_pad_size_divisor),
    neck=dict(_delete_=True, **_base_.stock_neck))
