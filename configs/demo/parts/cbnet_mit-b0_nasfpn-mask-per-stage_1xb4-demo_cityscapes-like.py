# parts set, second table: the demo CBNet with MMDet's CascadeRoIHead (the
# boundary-aware mask head on every stage, mask losses scaled by the stage
# weights, the stages' masks averaged at test) instead of one last-stage
# mask head.
_base_ = [
    '../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
    './_base_/parts.py',
]
model = dict(roi_head=dict(type=_base_.stock_roi_head_type))
