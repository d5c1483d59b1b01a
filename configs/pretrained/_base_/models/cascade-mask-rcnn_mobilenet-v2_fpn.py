# MMDet's stock Cascade Mask R-CNN (FPN, RPNHead, three softmax box stages
# at IoU 0.5/0.6/0.7, an FCN mask head per stage, BCE mask loss) on the
# pretrained MobileNetV2: the demo-size recipe of the `arch` / `parts`
# tables (64-channel neck and heads, 128 sampled RoIs) with its trunk
# swapped, so that the four recipes of configs/pretrained/ differ in their
# heads only. The data and budget come from the recipe configs.
_base_ = [
    '../../../demo/cascade-mask-rcnn_mit-b0_fpn_1xb4-demo_cityscapes-like.py',
    '../mobilenet-v2_finetune.py',
]

model = dict(
    backbone=dict(_delete_=True, **_base_.mnv2_trunk),
    neck=dict(in_channels=_base_.mnv2_channels))
optim_wrapper = _base_.mnv2_optim_wrapper
