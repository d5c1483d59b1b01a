# coco_street_coco_trunk_parts: MMDet's stock Cascade Mask R-CNN on YOLOX-
# Nano's COCO trunk with CBNet-PT's Cascade RPN (IoU / focal / GIoU
# objective, its regression losses weighted 1, NMS 0.8) in place of MMDet's
# RPNHead; nothing else changed.
_base_ = [
    '../cascade-mask-rcnn_yolox-nano-coco_fpn_1xb2-ft_coco-street.py',
    '../../demo/parts/_base_/parts.py',
]
model = _base_.cbnet_rpn_reg1_in_stock
