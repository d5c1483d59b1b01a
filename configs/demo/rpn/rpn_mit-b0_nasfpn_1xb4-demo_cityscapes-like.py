# The `rpn` comparison: MMDet's standard RPNHead (3 anchors per location,
# sampled BCE objectness, L1 regression; MMDet's Faster R-CNN settings) on
# the trunk and neck of crpn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py.
_base_ = './crpn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'

model = dict(
    rpn_head=dict(
        _delete_=True,
        type='RPNHead',
        in_channels=_base_.width,
        feat_channels=_base_.width,
        anchor_generator=dict(
            type='AnchorGenerator',
            scales=[8],
            ratios=[0.5, 1.0, 2.0],
            strides=[4, 8, 16, 32, 64]),
        bbox_coder=dict(
            type='DeltaXYWHBBoxCoder',
            target_means=[.0, .0, .0, .0],
            target_stds=[1.0, 1.0, 1.0, 1.0]),
        loss_cls=dict(
            type='CrossEntropyLoss', use_sigmoid=True, loss_weight=1.0),
        loss_bbox=dict(type='L1Loss', loss_weight=1.0)),
    train_cfg=dict(
        rpn=dict(
            _delete_=True,  # the base's None (the CRPN's defaults)
            assigner=dict(
                type='MaxIoUAssigner',
                pos_iou_thr=0.7,
                neg_iou_thr=0.3,
                min_pos_iou=0.3,
                match_low_quality=True,
                ignore_iof_thr=-1),
            sampler=dict(
                type='RandomSampler',
                num=256,
                pos_fraction=0.5,
                neg_pos_ub=-1,
                add_gt_as_proposals=False),
            allowed_border=-1,
            pos_weight=-1,
            debug=False)))
