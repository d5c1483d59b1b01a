# Dehaze-then-detect on real fog: the dark channel prior in front of the
# Cascade R-CNN of this folder, which trains and tests on dehazed images.
_base_ = [
    '../../../../configs/realfog/cascade-rcnn_mit-b0_fpn_1xb4-demo_voc-fog.py',
    '../_base_/attention_dehazer.py', './_base_/dehazers.py'
]

custom_imports = dict(
    imports=['cbnet_mmdet', 'cbnet_dehaze'], allow_failed_imports=False)

model = dict(
    data_preprocessor=dict(
        _base_.dehaze_preprocessor, dehaze=_base_.fog_dcp,
        dehaze_checkpoint=None))
