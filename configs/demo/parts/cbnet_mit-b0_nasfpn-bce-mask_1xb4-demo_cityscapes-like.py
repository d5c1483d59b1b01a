# parts set, second table: the demo CBNet with MMDet's FCNMaskHead and BCE
# mask loss instead of the boundary-aware loss.
_base_ = [
    '../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
    './_base_/parts.py',
]
model = dict(roi_head=dict(
    mask_head=dict(_delete_=True, **_base_.stock_mask_head)))
