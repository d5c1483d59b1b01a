# parts set: the stock cascade (SegFormer's MiT-B0) with CBNet's RoI head:
# one mask head on the last stage's positives (loss outside the stage
# weights) instead of one per stage; still MMDet's FCNMaskHead and BCE.
_base_ = [
    './cascade-mask-rcnn_mit-b0-gelu-ope_fpn_1xb4-demo_cityscapes-like.py'
]
model = dict(roi_head=dict(type=_base_.cbnet_roi_head_type))
