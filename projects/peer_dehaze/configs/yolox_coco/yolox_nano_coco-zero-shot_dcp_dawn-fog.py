# The dark channel prior in front of the COCO YOLOX-Nano zero-shot (no
# training): what dehazing alone does for a detector that never saw fog.
_base_ = [
    '../../../../configs/yolox_coco/yolox_nano_coco-zero-shot_dawn-fog.py',
    '../_base_/attention_dehazer.py', '../realfog/_base_/dehazers.py'
]

custom_imports = dict(
    imports=['cbnet_mmdet', 'cbnet_dehaze'], allow_failed_imports=False)

model = dict(
    data_preprocessor=dict(
        _base_.dehaze_preprocessor, dehaze=_base_.fog_dcp,
        dehaze_checkpoint=None))
