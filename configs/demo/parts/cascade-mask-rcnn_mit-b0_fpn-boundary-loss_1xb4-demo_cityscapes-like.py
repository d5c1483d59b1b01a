# parts set: the stock cascade (SegFormer's MiT-B0, a mask head per stage)
# with CBNet's boundary-aware mask loss (BCE + Dice + bounded Hausdorff)
# instead of BCE.
_base_ = [
    './cascade-mask-rcnn_mit-b0-gelu-ope_fpn_1xb4-demo_cityscapes-like.py'
]
model = dict(roi_head=dict(
    mask_head=dict(_delete_=True, **_base_.cbnet_mask_head)))
