# parts set: the stock cascade (SegFormer's MiT-B0) with CBNet's NAS-FPN
# neck (merging cells on strides 4-64, one stack) instead of FPN.
_base_ = [
    './cascade-mask-rcnn_mit-b0-gelu-ope_fpn_1xb4-demo_cityscapes-like.py'
]
model = dict(
    data_preprocessor=dict(pad_size_divisor=_base_.cbnet_pad_size_divisor),
    neck=dict(_delete_=True, **_base_.cbnet_neck))
