# The revised CBNet with MMDet's RPNHead (and its training settings, NMS
# 0.7) in place of the Cascade RPN, on the pretrained MobileNetV2: the
# parts set's row "CBNet revised -CRPN" with its trunk swapped.
_base_ = [
    '../../../demo/parts/cbnet_mit-b0_nasfpn-mask-per-stage-softmax-cls-'
    'rpn_1xb4-demo_cityscapes-like.py',
    '../mobilenet-v2_finetune.py',
]

model = dict(
    backbone=dict(_delete_=True, **_base_.mnv2_trunk),
    neck=dict(in_channels=_base_.mnv2_channels))
optim_wrapper = _base_.mnv2_optim_wrapper
