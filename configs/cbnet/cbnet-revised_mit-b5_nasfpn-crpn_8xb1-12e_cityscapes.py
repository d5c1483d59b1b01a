# The revised CBNet at paper size: the paper's CBNet-B5 recipe
# (./cbnet_mit-b5_nasfpn-crpn_8xb1-12e_cityscapes.py, unchanged, stays the
# headline config) with the three changes the parts tables
# chose on the generated benchmark (docs/accuracy.md "A CBNet that wins";
# measured at demo size, MiT-B0 from scratch, not on Cityscapes):
_base_ = './cbnet_mit-b5_nasfpn-crpn_8xb1-12e_cityscapes.py'

crpn_reg_weight = 1.0  # paper eq. (3): lambda_IoU = lambda_GIoU = 10
model = dict(
    rpn_head=dict(
        loss_iou=dict(loss_weight=crpn_reg_weight),
        loss_giou=dict(loss_weight=crpn_reg_weight)),
    roi_head=dict(
        # a boundary-aware mask head on every stage, its losses scaled by the
        # stage weights, the stages' masks averaged at test (MMDet's cascade)
        # instead of the paper's one head on the last stage
        type='CascadeRoIHead',
        # softmax over C + 1 classes instead of the paper's C sigmoids (4)
        bbox_head=[
            dict(head, loss_cls=dict(
                type='CrossEntropyLoss', use_sigmoid=False, loss_weight=1.0))
            for head in _base_.model.roi_head.bbox_head
        ]))
