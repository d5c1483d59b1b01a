# coco_street_coco_trunk_parts: MMDet's stock Cascade Mask R-CNN on YOLOX-
# Nano's COCO trunk with CBNet's boundary-aware mask loss (BCE + Dice +
# bounded Hausdorff, CBNet-PT's mask head, one per stage) in place of BCE;
# nothing else changed.
_base_ = [
    '../cascade-mask-rcnn_yolox-nano-coco_fpn_1xb2-ft_coco-street.py',
    '../../demo/parts/_base_/parts.py',
]
model = dict(roi_head=dict(
    mask_head=dict(_delete_=True, **_base_.cbnet_mask_head)))
