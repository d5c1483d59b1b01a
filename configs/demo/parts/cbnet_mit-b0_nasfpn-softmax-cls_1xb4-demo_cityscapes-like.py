# parts set, second table: the demo CBNet with MMDet's softmax RoI
# classification instead of the paper's per-class sigmoid (eq. (4)).
_base_ = [
    '../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
    './_base_/parts.py',
]
model = dict(roi_head=dict(bbox_head=[
    dict(head, loss_cls=_base_.stock_loss_cls)
    for head in _base_.model.roi_head.bbox_head
]))
