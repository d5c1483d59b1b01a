# parts set, second table: the demo CBNet with MMDet's RPNHead (and its
# training settings, NMS 0.7) instead of the Cascade RPN.
_base_ = [
    '../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
    './_base_/parts.py',
]
model = dict(
    rpn_head=dict(_delete_=True, **_base_.stock_rpn_head),
    train_cfg=dict(
        # the base's rpn is None (the Cascade RPN's own defaults)
        rpn=dict(_delete_=True, **_base_.stock_rpn_train_cfg),
        rpn_proposal=dict(nms=_base_.stock_rpn_nms)),
    test_cfg=dict(rpn=dict(nms=_base_.stock_rpn_nms)))
