# parts set: the stock cascade (SegFormer's MiT-B0) with CBNet's Cascade RPN
# (IoU / focal / GIoU objective, its NMS 0.8) instead of MMDet's RPNHead.
_base_ = [
    './cascade-mask-rcnn_mit-b0-gelu-ope_fpn_1xb4-demo_cityscapes-like.py'
]
model = _base_.cbnet_rpn_in_stock
