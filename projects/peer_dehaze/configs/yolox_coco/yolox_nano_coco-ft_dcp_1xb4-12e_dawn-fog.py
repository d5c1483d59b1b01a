# Dehaze-then-detect on a COCO-pretrained YOLO, as YOLO-Vehicle-Pro builds
# it: the dark channel prior (He et al.; no weights) in front of the
# COCO YOLOX-Nano, which fine-tunes and tests on the dehazed photos
# (configs/yolox_coco/yolox_nano_coco-ft_1xb4-12e_dawn-fog.py otherwise).
_base_ = [
    '../../../../configs/yolox_coco/yolox_nano_coco-ft_1xb4-12e_dawn-fog.py',
    '../_base_/attention_dehazer.py', '../realfog/_base_/dehazers.py'
]

custom_imports = dict(
    imports=['cbnet_mmdet', 'cbnet_dehaze'], allow_failed_imports=False)

model = dict(
    data_preprocessor=dict(
        _base_.dehaze_preprocessor, dehaze=_base_.fog_dcp,
        dehaze_checkpoint=None))
