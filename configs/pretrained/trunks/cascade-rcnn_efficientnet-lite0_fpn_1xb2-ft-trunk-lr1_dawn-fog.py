# MMDet's stock Cascade R-CNN on an ImageNet EfficientNet-Lite0
# (CBNetEfficientNetLite) in place of MobileNetV2, everything else as
# ../finetune/cascade-rcnn_mobilenet-v2_fpn_1xb2-ft-trunk-lr1_dawn-fog.py
# (the trunk at the full lr, the better setting measured there), so that
# the rows of compare_recipes.py --set realfog_pretrained_trunks differ in
# the trunk only. Over 3 seeds Lite0 beats MobileNetV2 on DAWN's real fog
# by more than a seed std (docs/accuracy.md, "Which ImageNet trunk").
# Weights, once: python tools/model_converters/fetch_pretrained.py
# efficientnet_lite0 (../_base_/efficientnet-lite0_trunk.py).
_base_ = [
    '../finetune/cascade-rcnn_mobilenet-v2_fpn_1xb2-ft-trunk-lr1_dawn-fog.py',
    '../_base_/efficientnet-lite0_trunk.py',
]

model = dict(
    data_preprocessor=dict(**_base_.lite0_preprocessor),
    backbone=dict(_delete_=True, **_base_.lite0_trunk),
    neck=dict(in_channels=_base_.lite0_channels))
