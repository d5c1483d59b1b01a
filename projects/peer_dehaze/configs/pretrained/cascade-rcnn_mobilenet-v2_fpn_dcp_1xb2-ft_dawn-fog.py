# Dehaze-then-detect on real fog with a pretrained trunk (compare_recipes.py
# --set realfog_pretrained): the dark channel prior (He et al., the peer's
# training-free dehazer; no weights to train first) in front of MMDet's
# stock Cascade R-CNN on the pretrained MobileNetV2, which fine-tunes and
# tests on the dehazed photos.
_base_ = [
    '../../../../configs/pretrained/'
    'cascade-rcnn_mobilenet-v2_fpn_1xb2-ft_dawn-fog.py',
    '../_base_/attention_dehazer.py', '../realfog/_base_/dehazers.py'
]

custom_imports = dict(
    imports=['cbnet_mmdet', 'cbnet_dehaze'], allow_failed_imports=False)

model = dict(
    data_preprocessor=dict(
        _base_.dehaze_preprocessor, dehaze=_base_.fog_dcp,
        dehaze_checkpoint=None))
