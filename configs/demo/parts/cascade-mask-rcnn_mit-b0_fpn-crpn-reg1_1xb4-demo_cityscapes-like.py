# parts set, diagnostic of the revised CBNet: "stock +CRPN" with
# the Cascade RPN's regression losses weighted 1 instead of the paper's
# lambda_IoU = lambda_GIoU = 10 (eq. (3)) — does the Cascade RPN help the
# stock cascade once its losses no longer dominate the shared trunk?
_base_ = ['./cascade-mask-rcnn_mit-b0_fpn-crpn_1xb4-demo_cityscapes-like.py']
model = dict(rpn_head=_base_.crpn_reg1)  # paper: 10 (parts.py)
