# realfog_pretrained_parts: MMDet's stock Cascade R-CNN on the pretrained
# MobileNetV2 (trunk at the full lr, as configs/pretrained/finetune/) with the
# revised CBNet's Cascade RPN (IoU / focal / GIoU objective with its regression
# losses weighted 1, NMS 0.8) in place of MMDet's RPNHead; nothing else
# changed.
_base_ = [
    '../finetune/cascade-rcnn_mobilenet-v2_fpn_1xb2-ft-trunk-lr1_'
    'dawn-fog.py',
    '../../demo/parts/_base_/parts.py',
]
model = _base_.cbnet_rpn_reg1_in_stock
