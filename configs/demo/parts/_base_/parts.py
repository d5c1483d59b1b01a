# The parts in which the demo CBNet and MMDet's stock Cascade Mask R-CNN
# differ, one named dict each, for the `parts` set of the comparison harness
# (tools/analysis_tools/compare_recipes.py --set parts, docs/accuracy.md):
# every config of configs/demo/parts/ is one of the two demo recipes with
# ONE part swapped for the other recipe's. The values are those of
# ../../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py (cbnet_*) and of
# ../../cascade-mask-rcnn_mit-b0_fpn_1xb4-demo_cityscapes-like.py, i.e. of
# mmdet::_base_/models/cascade-mask-rcnn_r50_fpn.py at demo width (stock_*);
# tests/test_configs/test_parts_configs.py checks that swapping every part
# of one recipe gives the other.
part_width = 64  # neck/head channels of every demo recipe (paper: 256)
part_in_channels = [32, 64, 160, 256]  # MiT-B0 stage widths

# 1. the trunk's activation and positional scheme (paper II.A, formula (1))
cbnet_trunk = dict(act_cfg=dict(type='CBNetMish'), pos_encoding='cspe')
# SegFormer's MiT: GELU and overlapping patch embedding
stock_trunk = dict(act_cfg=dict(type='GELU'), pos_encoding='ope')

# 2. the neck: NAS-FPN merging cells on strides 4-64, one stack (the demo's)
cbnet_neck = dict(
    type='CBNetNASFPN',
    in_channels=part_in_channels,
    out_channels=part_width,
    num_outs=5,
    stack_times=1,
    fine_path='cells',
    norm_cfg=dict(type='BN', requires_grad=True))
cbnet_pad_size_divisor = 64  # the NAS-FPN's coarsest level has stride 64
stock_neck = dict(
    type='FPN',
    in_channels=part_in_channels,
    out_channels=part_width,
    num_outs=5)
stock_pad_size_divisor = 32

# 3. the RPN with its training and test settings: CBNet's two-stage Cascade
# RPN (paper (2)-(3); train_cfg.rpn None takes the head's per-stage
# defaults) against MMDet's RPNHead
cbnet_rpn_head = dict(
    type='CBNetCascadeRPNHead',
    in_channels=part_width,
    feat_channels=part_width,
    strides=(4, 8, 16, 32, 64),
    loss_iou=dict(type='IoULoss', mode='linear', loss_weight=10.0),
    loss_obj=dict(
        type='FocalLoss', use_sigmoid=True, gamma=2.0, alpha=0.25,
        loss_weight=1.0),
    loss_giou=dict(type='GIoULoss', loss_weight=10.0))
cbnet_rpn_train_cfg = None
cbnet_rpn_nms = dict(type='nms', iou_threshold=0.8)
stock_rpn_head = dict(
    type='RPNHead',
    in_channels=part_width,
    feat_channels=part_width,
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
    loss_bbox=dict(type='SmoothL1Loss', beta=1.0 / 9.0, loss_weight=1.0))
stock_rpn_train_cfg = dict(
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
    allowed_border=0,
    pos_weight=-1,
    debug=False)
stock_rpn_nms = dict(type='nms', iou_threshold=0.7)
# the model delta that puts that RPN (head, training settings, NMS) in
# place of a CBNet's Cascade RPN, whose base train_cfg.rpn is None
stock_rpn_in_cbnet = dict(
    rpn_head=dict(_delete_=True, **stock_rpn_head),
    train_cfg=dict(
        rpn=dict(_delete_=True, **stock_rpn_train_cfg),
        rpn_proposal=dict(nms=stock_rpn_nms)),
    test_cfg=dict(rpn=dict(nms=stock_rpn_nms)))

# 4. the IoU thresholds of the three box stages (paper II.C.1; MMDet's)
cbnet_stage_ious = (0.5, 0.7, 0.9)
stock_stage_ious = (0.5, 0.6, 0.7)

# 5. where the mask head runs: CBNet's one head on the last stage's
# positives, its loss outside the stage weights (paper II.C, eq. (10)),
# against MMDet's head per stage, mask losses scaled by the stage weights
# and the three stages' masks averaged at test time
cbnet_roi_head_type = 'CBNetCascadeRoIHead'
stock_roi_head_type = 'CascadeRoIHead'

# 6. the mask loss: boundary-aware (BCE + Dice + bounded Hausdorff, paper
# (6)-(9)) against MMDet's per-pixel BCE
part_num_classes = 8  # Cityscapes instance classes
cbnet_mask_head = dict(
    type='CBNetBoundaryMaskHead',
    num_convs=2,  # the demo's mask head depth and width
    in_channels=part_width,
    conv_out_channels=part_width,
    num_classes=part_num_classes,
    # no edge-map branch: eq. (9) has no edge-map loss
    loss_edge=None,
    loss_mask=dict(
        type='CBNetBoundaryAwareLoss',
        use_shape=True,
        use_edge=True,
        lambda_shape=1.0,
        lambda_edge=1.0,
        loss_weight=1.0))
stock_mask_head = dict(
    type='FCNMaskHead',
    num_convs=2,
    in_channels=part_width,
    conv_out_channels=part_width,
    num_classes=part_num_classes,
    loss_mask=dict(type='CrossEntropyLoss', use_mask=True, loss_weight=1.0))

# 7. RoI classification: C sigmoid logits, binary cross-entropy (paper eq.
# (4)) against MMDet's softmax over C + 1 classes
cbnet_loss_cls = dict(type='CBNetSigmoidCrossEntropyLoss', loss_weight=1.0)
stock_loss_cls = dict(
    type='CrossEntropyLoss', use_sigmoid=False, loss_weight=1.0)

# Not a part: the Cascade RPN's regression losses weighted 1 instead of the
# paper's lambda_IoU = lambda_GIoU = 10 (eq. (3)), the change of the revised
# CBNet (docs/accuracy.md "A CBNet that wins"), as an rpn_head delta
crpn_reg_weight = 1.0
crpn_reg1 = dict(
    loss_iou=dict(loss_weight=crpn_reg_weight),
    loss_giou=dict(loss_weight=crpn_reg_weight))

# the model deltas that put CBNet's Cascade RPN (head, training settings,
# NMS) in place of a stock recipe's RPNHead: as the paper weights its
# regression losses, and weighted 1 (the revised CBNet's, CBNet-PT's)
cbnet_rpn_in_stock = dict(
    rpn_head=dict(_delete_=True, **cbnet_rpn_head),
    train_cfg=dict(
        rpn=cbnet_rpn_train_cfg, rpn_proposal=dict(nms=cbnet_rpn_nms)),
    test_cfg=dict(rpn=dict(nms=cbnet_rpn_nms)))
cbnet_rpn_reg1_in_stock = dict(
    cbnet_rpn_in_stock,
    rpn_head=dict(
        cbnet_rpn_in_stock['rpn_head'],
        loss_iou=dict(cbnet_rpn_head['loss_iou'],
                      loss_weight=crpn_reg_weight),
        loss_giou=dict(cbnet_rpn_head['loss_giou'],
                       loss_weight=crpn_reg_weight)))
