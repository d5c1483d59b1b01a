# A light single-stage detector on the same pretrained MobileNetV2 (issue
# 45): the edge model's head at the realfog_pretrained set's 640 px, so the
# table separates what the light head costs from what the edge model's
# 320 px input costs (fcos-lite_..._dawn-fog-320.py, the edge model).
# MMDet's FCOS with its improvements (centre sampling, centre-ness on the
# regression branch, normalised targets, GIoU) made thin for one CPU core:
# three FPN levels (strides 8/16/32 from the trunk's 32, 96 and 1280
# channels; the stride-4 output is left unused), 64 channels, one
# convolution per branch instead of four of 256 (chosen by timing on one
# thread at 640x360 frames, projects/edge_serving/README.md "The edge
# model"). Boxes only; the trunk, its fine-tuning (frozen stem, BN kept,
# trunk lr x0.1), the data and the budget are the other recipes'.
_base_ = [
    './_base_/models/cascade-mask-rcnn_mobilenet-v2_fpn.py',
    './_base_/datasets/dawn-fog_box.py',
]

width = 64
model = dict(
    _delete_=True,
    type='FCOS',
    data_preprocessor=dict(_base_.model.data_preprocessor, pad_mask=False),
    backbone=_base_.mnv2_trunk,
    neck=dict(
        type='FPN',
        in_channels=_base_.mnv2_channels,
        out_channels=width,
        start_level=1,  # strides 8, 16, 32
        num_outs=3),
    bbox_head=dict(
        type='FCOSHead',
        num_classes=8,  # the 8 Cityscapes classes DAWN is read as
        in_channels=width,
        feat_channels=width,
        stacked_convs=1,
        strides=[8, 16, 32],
        # MMDet's five ranges folded into three levels: the last takes
        # everything above 128 px
        regress_ranges=((-1, 64), (64, 128), (128, 1e8)),
        norm_on_bbox=True,
        centerness_on_reg=True,
        center_sampling=True,
        conv_bias=True,
        loss_cls=dict(
            type='FocalLoss',
            use_sigmoid=True,
            gamma=2.0,
            alpha=0.25,
            loss_weight=1.0),
        loss_bbox=dict(type='GIoULoss', loss_weight=1.0),
        loss_centerness=dict(
            type='CrossEntropyLoss', use_sigmoid=True, loss_weight=1.0)),
    test_cfg=dict(
        nms_pre=1000,
        min_bbox_size=0,
        score_thr=0.05,
        nms=dict(type='nms', iou_threshold=0.6),
        max_per_img=100))
# the trunk at a tenth of the lr, the neck and head at the recipes' 2e-4
# (the base's rpn_head / roi_head keys match nothing here)
optim_wrapper = _base_.mnv2_optim_wrapper

# the real-fog data in place of the demo's
data_root = _base_.fog_data_root
train_dataloader = dict(_delete_=True, **_base_.fog_train_dataloader)
val_dataloader = test_dataloader = dict(
    _delete_=True, **_base_.fog_test_dataloader)
val_evaluator = test_evaluator = _base_.fog_evaluator
