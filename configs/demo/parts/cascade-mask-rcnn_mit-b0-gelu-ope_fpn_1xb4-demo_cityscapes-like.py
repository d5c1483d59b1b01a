# parts set (compare_recipes.py --set parts), first table's baseline: MMDet's
# stock Cascade Mask R-CNN on SegFormer's MiT-B0 (GELU, overlapping patch
# embedding); the other configs of that table each swap in ONE part of the
# demo CBNet (./_base_/parts.py).
_base_ = [
    '../cascade-mask-rcnn_mit-b0_fpn_1xb4-demo_cityscapes-like.py',
    './_base_/parts.py',
]
model = dict(backbone=dict(**_base_.stock_trunk))
