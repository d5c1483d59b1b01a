# MMDet's YOLOX-Tiny at demo size: the YOLO-family detector of the real-fog
# set (configs/realfog/yolox_tiny_1xb4-demo_voc-fog.py) and, behind a
# frozen dehazer, of the peer baseline's dehaze-then-detect recipes
# (projects/peer_dehaze). A shared base, not a recipe of its own.
# mmyolo's YOLOv8 (the peer paper's base) is not used: mmyolo 0.6.0 (the
# latest) asserts mmcv < 2.1.0 at import and our stack pins mmcv 2.1.0
# (checked with `pip download --no-deps mmyolo` and its mmyolo/__init__.py).
# MMDet's YOLOX-Tiny stands in (CSPDarknet + PAFPN + decoupled anchor-free
# head, MMDet's yolox_tiny_8xb8-300e_coco model).
# Data, schedule (12 epochs x 12 iterations of 4 images, AdamW 1e-3, poly)
# and data_root are the CBNet demo's, so the comparison harness can train
# it with the same budget. YOLOX predicts boxes only: the evaluator is
# CocoMetric with metric='bbox'; mask AP and mIoU are not reported (the
# harness must show them as '-', not 0).
_base_ = '../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'

norm_cfg = dict(type='BN', momentum=0.03, eps=0.001)  # YOLOX's
act_cfg = dict(type='Swish')
widths = [96, 192, 384]  # YOLOX-Tiny: widen_factor 0.375

model = dict(
    _delete_=True,
    type='YOLOX',
    # YOLOX takes raw 0-255 BGR (no mean/std, no channel swap); no
    # BatchSyncRandomResize on the 256x128 demo images
    data_preprocessor=dict(type='DetDataPreprocessor', pad_size_divisor=32),
    backbone=dict(
        type='CSPDarknet',
        deepen_factor=0.33,
        widen_factor=0.375,
        out_indices=(2, 3, 4),
        use_depthwise=False,
        spp_kernal_sizes=(5, 9, 13),
        norm_cfg=norm_cfg,
        act_cfg=act_cfg),
    neck=dict(
        type='YOLOXPAFPN',
        in_channels=widths,
        out_channels=widths[0],
        num_csp_blocks=1,
        use_depthwise=False,
        upsample_cfg=dict(scale_factor=2, mode='nearest'),
        norm_cfg=norm_cfg,
        act_cfg=act_cfg),
    bbox_head=dict(
        type='YOLOXHead',
        num_classes=8,
        in_channels=widths[0],
        feat_channels=widths[0],
        stacked_convs=2,
        strides=(8, 16, 32),
        use_depthwise=False,
        norm_cfg=norm_cfg,
        act_cfg=act_cfg,
        loss_cls=dict(
            type='CrossEntropyLoss', use_sigmoid=True, reduction='sum',
            loss_weight=1.0),
        loss_bbox=dict(
            type='IoULoss', mode='square', eps=1e-16, reduction='sum',
            loss_weight=5.0),
        loss_obj=dict(
            type='CrossEntropyLoss', use_sigmoid=True, reduction='sum',
            loss_weight=1.0),
        loss_l1=dict(type='L1Loss', reduction='sum', loss_weight=1.0)),
    train_cfg=dict(assigner=dict(type='SimOTAAssigner', center_radius=2.5)),
    test_cfg=dict(score_thr=0.01, nms=dict(type='nms', iou_threshold=0.65)))

# a list, like the demo's (CocoMetric + mIoU), with the box metric only
val_evaluator = [
    dict(
        type='CocoMetric',
        ann_file=_base_.data_root + _base_.val_ann_file,
        metric='bbox')
]
test_evaluator = val_evaluator
