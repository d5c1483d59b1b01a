# parts set: the stock cascade (SegFormer's MiT-B0) with CBNet's Cascade RPN
# (IoU / focal / GIoU objective, its NMS 0.8) instead of MMDet's RPNHead.
_base_ = [
    './cascade-mask-rcnn_mit-b0-gelu-ope_fpn_1xb4-demo_cityscapes-like.py'
]
model = dict(
    rpn_head=dict(_delete_=True, **_base_.cbnet_rpn_head),
    train_cfg=dict(
        rpn=_base_.cbnet_rpn_train_cfg,
        rpn_proposal=dict(nms=_base_.cbnet_rpn_nms)),
    test_cfg=dict(rpn=dict(nms=_base_.cbnet_rpn_nms)))
