# The revised CBNet's box path (NAS-FPN, Cascade RPN with regression
# weights 1, IoUs .5/.7/.9, softmax) on the ImageNet EfficientNet-Lite0,
# everything else as
# ../finetune/cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft-trunk-lr1_dawn-fog.py:
# the question of compare_recipes.py --set realfog_pretrained_trunks is
# whether CBNet's heads gain from the better trunk what the stock cascade
# gains (docs/accuracy.md, "Which ImageNet trunk").
# Weights, once: python tools/model_converters/fetch_pretrained.py
# efficientnet_lite0 (../_base_/efficientnet-lite0_trunk.py).
_base_ = [
    '../finetune/cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft-trunk-'
    'lr1_dawn-fog.py',
    '../_base_/efficientnet-lite0_trunk.py',
]

model = dict(
    data_preprocessor=dict(**_base_.lite0_preprocessor),
    backbone=dict(_delete_=True, **_base_.lite0_trunk),
    neck=dict(in_channels=_base_.lite0_channels))
