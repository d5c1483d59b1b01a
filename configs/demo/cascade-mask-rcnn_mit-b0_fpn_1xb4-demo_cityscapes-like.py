# Baseline of the `arch` comparison (compare_recipes.py --set arch): MMDet's
# stock Cascade Mask R-CNN (FPN, RPNHead, MMDet's cascade with a mask head
# per stage, softmax classification, BCE mask loss, IoU thresholds
# 0.5/0.6/0.7) on the SAME MiT-B0 trunk, widths, data and schedule as the
# CBNet demo, so the comparison isolates CBNet's neck, RPN, RoI head and
# mask loss. Only the widths and class count differ from MMDet's model.
_base_ = [
    'mmdet::_base_/models/cascade-mask-rcnn_r50_fpn.py',
    './_base_/cityscapes-like_1xb4-12e.py',
]

custom_imports = dict(imports=['cbnet_mmdet'], allow_failed_imports=False)
width = 64  # as the CBNet demo
num_classes = 8

model = dict(
    backbone=dict(_delete_=True, **_base_.trunk),
    neck=dict(in_channels=_base_.trunk_channels, out_channels=width),
    rpn_head=dict(in_channels=width, feat_channels=width),
    roi_head=dict(
        bbox_roi_extractor=dict(out_channels=width),
        bbox_head=[
            dict(head, in_channels=width, fc_out_channels=256,
                 num_classes=num_classes)
            for head in _base_.model.roi_head.bbox_head
        ],
        mask_roi_extractor=dict(out_channels=width),
        # the CBNet demo's mask head depth and width
        mask_head=dict(num_convs=2, in_channels=width,
                       conv_out_channels=width, num_classes=num_classes)),
    # the CBNet demo's proposal and RoI sampling budget
    train_cfg=dict(
        rpn_proposal=dict(nms_pre=1000, max_per_img=300),
        rcnn=[
            dict(stage, sampler=dict(stage.sampler, num=128))
            for stage in _base_.model.train_cfg.rcnn
        ]),
    test_cfg=dict(rpn=dict(nms_pre=500, max_per_img=300)))
