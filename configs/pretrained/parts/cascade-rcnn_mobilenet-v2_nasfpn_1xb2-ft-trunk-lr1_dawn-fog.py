# realfog_pretrained_parts: MMDet's stock Cascade R-CNN on the pretrained
# MobileNetV2 (trunk at the full lr, as configs/pretrained/finetune/) with
# CBNet's NAS-FPN (merging cells on strides 4-64, one stack, padding to 64) in
# place of the FPN; nothing else changed.
_base_ = [
    '../finetune/cascade-rcnn_mobilenet-v2_fpn_1xb2-ft-trunk-lr1_'
    'dawn-fog.py',
    '../../demo/parts/_base_/parts.py',
]
model = dict(
    data_preprocessor=dict(pad_size_divisor=_base_.cbnet_pad_size_divisor),
    neck=dict(_delete_=True,
              **dict(_base_.cbnet_neck, in_channels=_base_.mnv2_channels)))
