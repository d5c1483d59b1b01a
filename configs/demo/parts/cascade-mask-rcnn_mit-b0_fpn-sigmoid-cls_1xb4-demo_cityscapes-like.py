# parts set: the stock cascade (SegFormer's MiT-B0) with the paper's RoI
# classification (eq. (4): C sigmoid logits, binary cross-entropy) instead
# of MMDet's softmax over C + 1 classes.
_base_ = [
    './cascade-mask-rcnn_mit-b0-gelu-ope_fpn_1xb4-demo_cityscapes-like.py'
]
model = dict(roi_head=dict(bbox_head=[
    dict(head, loss_cls=_base_.cbnet_loss_cls)
    for head in _base_.model.roi_head.bbox_head
]))
