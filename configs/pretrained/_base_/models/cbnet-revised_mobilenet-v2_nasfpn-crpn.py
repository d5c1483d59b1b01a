# The revised CBNet (docs/accuracy.md "A CBNet that wins"): the paper's
# heads with a boundary-aware mask head on every stage (MMDet's
# CascadeRoIHead), softmax RoI classification and the Cascade RPN's
# regression losses weighted 1, on the pretrained MobileNetV2
# (configs/demo/cbnet-revised_* with its trunk swapped).
_base_ = [
    '../../../demo/cbnet-revised_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
    '../mobilenet-v2_finetune.py',
]

model = dict(
    backbone=dict(_delete_=True, **_base_.mnv2_trunk),
    neck=dict(in_channels=_base_.mnv2_channels))
optim_wrapper = _base_.mnv2_optim_wrapper
