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
model = dict(
    rpn_head=dict(_delete_=True,
                  **dict(_base_.cbnet_rpn_head,
                         loss_iou=dict(_base_.cbnet_rpn_head.loss_iou,
                                       loss_weight=_base_.crpn_reg_weight),
                         loss_giou=dict(_base_.cbnet_rpn_head.loss_giou,
                                        loss_weight=_base_.crpn_reg_weight))),
    train_cfg=dict(
        rpn=_base_.cbnet_rpn_train_cfg,
        rpn_proposal=dict(nms=_base_.cbnet_rpn_nms)),
    test_cfg=dict(rpn=dict(nms=_base_.cbnet_rpn_nms)))
