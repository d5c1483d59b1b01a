# The `rpn` comparison (compare_recipes.py --set rpn): proposal recall
# (AR@100/300/1000) of CBNet's Cascade RPN against MMDet's RPNHead and
# MMDet's own CascadeRPNHead. Each is MMDet's `RPN` detector on the SAME
# MiT-B0 trunk and demo NAS-FPN neck, data and schedule as the CBNet demo;
# only the head differs, and every head keeps 1000 proposals after the
# same NMS (IoU 0.7) so the recall figures compare like with like.
_base_ = '../_base_/cityscapes-like_1xb4-12e.py'

model = dict(
    type='RPN',
    data_preprocessor=dict(
        type='DetDataPreprocessor',
        mean=[123.675, 116.28, 103.53],
        std=[58.395, 57.12, 57.375],
        bgr_to_rgb=True,
        pad_size_divisor=64),  # the coarsest level has stride 64
    backbone=_base_.trunk,
    neck=dict(
        type='CBNetNASFPN',
        in_channels=_base_.trunk_channels,
        out_channels=_base_.width,
        num_outs=5,  # strides 4..64
        stack_times=1,  # the demo's
        norm_cfg=dict(type='BN', requires_grad=True)),
    rpn_head=dict(
        type='CBNetCascadeRPNHead',
        in_channels=_base_.width,
        feat_channels=_base_.width),
    train_cfg=dict(rpn=None),  # the head's per-stage defaults
    test_cfg=dict(
        rpn=dict(
            nms_pre=2000,
            max_per_img=1000,
            nms=dict(type='nms', iou_threshold=0.7),
            min_bbox_size=0)))

val_evaluator = [
    dict(
        type='CocoMetric',
        ann_file=_base_.data_root + _base_.val_ann_file,
        metric='proposal',
        proposal_nums=(100, 300, 1000))
]
test_evaluator = val_evaluator
