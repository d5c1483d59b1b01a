# The paper's CBNet heads (section II: NAS-FPN adapter neck, the two-stage
# Cascade RPN with its IoU / focal / GIoU objective at weights 10, cascade
# IoUs 0.5/0.7/0.9, sigmoid RoI classification, the boundary-aware mask
# head on the last stage only) on the pretrained MobileNetV2: the demo CBNet
# (64-channel neck and heads) with its MiT-B0 trunk swapped.
_base_ = [
    '../../../demo/cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
    '../mobilenet-v2_finetune.py',
]

model = dict(
    backbone=dict(_delete_=True, **_base_.mnv2_trunk),
    neck=dict(in_channels=_base_.mnv2_channels))
optim_wrapper = _base_.mnv2_optim_wrapper
