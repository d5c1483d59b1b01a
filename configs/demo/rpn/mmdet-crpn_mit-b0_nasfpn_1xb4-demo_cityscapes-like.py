# The `rpn` comparison: MMDet's own CascadeRPNHead with the settings of
# MMDet's configs/cascade_rpn/cascade-rpn_r50-caffe_fpn_1x_coco.py (stage 1
# IoU loss without sampling; stage 2 sampled BCE objectness and IoU loss),
# on the trunk and neck of crpn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py.
# (MMDet's config also passes the 2.x arguments `sampling` and
# `linear=True`; in 3.x the sampler in train_cfg decides and IoULoss takes
# mode='linear'.)
_base_ = './crpn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'

stage1 = dict(
    type='StageCascadeRPNHead',
    in_channels=_base_.width,
    feat_channels=_base_.width,
    anchor_generator=dict(
        type='AnchorGenerator',
        scales=[8],
        ratios=[1.0],
        strides=[4, 8, 16, 32, 64]),
    adapt_cfg=dict(type='dilation', dilation=3),
    bridged_feature=True,
    with_cls=False,
    reg_decoded_bbox=True,
    bbox_coder=dict(
        type='DeltaXYWHBBoxCoder',
        target_means=(.0, .0, .0, .0),
        target_stds=(0.1, 0.1, 0.5, 0.5)),
    loss_bbox=dict(type='IoULoss', mode='linear', loss_weight=10.0))
stage2 = dict(
    type='StageCascadeRPNHead',
    in_channels=_base_.width,
    feat_channels=_base_.width,
    adapt_cfg=dict(type='offset'),
    bridged_feature=False,
    with_cls=True,
    reg_decoded_bbox=True,
    bbox_coder=dict(
        type='DeltaXYWHBBoxCoder',
        target_means=(.0, .0, .0, .0),
        target_stds=(0.05, 0.05, 0.1, 0.1)),
    loss_cls=dict(type='CrossEntropyLoss', use_sigmoid=True, loss_weight=1.0),
    loss_bbox=dict(type='IoULoss', mode='linear', loss_weight=10.0))
model = dict(
    rpn_head=dict(
        _delete_=True,
        type='CascadeRPNHead',
        num_classes=1,  # class-agnostic proposals
        num_stages=2,
        stages=[stage1, stage2]),
    train_cfg=dict(rpn=[
        dict(
            assigner=dict(
                type='RegionAssigner', center_ratio=0.2, ignore_ratio=0.5),
            allowed_border=-1,
            pos_weight=-1,
            debug=False),
        dict(
            assigner=dict(
                type='MaxIoUAssigner',
                pos_iou_thr=0.7,
                neg_iou_thr=0.7,
                min_pos_iou=0.3,
                ignore_iof_thr=-1),
            sampler=dict(
                type='RandomSampler',
                num=256,
                pos_fraction=0.5,
                neg_pos_ub=-1,
                add_gt_as_proposals=False),
            allowed_border=-1,
            pos_weight=-1,
            debug=False)
    ]))
