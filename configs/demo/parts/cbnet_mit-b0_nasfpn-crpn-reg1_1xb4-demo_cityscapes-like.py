# parts set, diagnostic of the revised CBNet: the demo CBNet
# with only the Cascade RPN's regression losses weighted 1 instead of the
# paper's 10 (eq. (3)): what that change is worth without the head changes.
_base_ = [
    '../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
    './_base_/parts.py',
]
model = dict(rpn_head=_base_.crpn_reg1)  # paper: 10 (parts.py)
