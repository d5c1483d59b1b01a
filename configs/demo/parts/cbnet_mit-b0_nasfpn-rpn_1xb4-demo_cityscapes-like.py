# parts set, second table: the demo CBNet with MMDet's RPNHead (and its
# training settings, NMS 0.7) instead of the Cascade RPN.
_base_ = [
    '../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
    './_base_/parts.py',
]
model = _base_.stock_rpn_in_cbnet
