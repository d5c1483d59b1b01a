# coco_street_coco_trunk_parts: MMDet's stock Cascade Mask R-CNN on YOLOX-
# Nano's COCO trunk with the paper's RoI head: one mask head on the last
# stage's positives (its loss outside the stage weights) instead of one per
# stage; still MMDet's FCNMaskHead and BCE. CBNet-PT keeps a head per stage
# (the revision): this row asks whether the paper's choice pays here.
_base_ = [
    '../cascade-mask-rcnn_yolox-nano-coco_fpn_1xb2-ft_coco-street.py',
    '../../demo/parts/_base_/parts.py',
]
model = dict(roi_head=dict(type=_base_.cbnet_roi_head_type))
