# Baseline (paper Tables 1-2): Faster R-CNN, ResNeXt-101 (64x4d) FPN, on the
# 8-class Cityscapes data. MMDet's public Cityscapes recipe (its R50 config:
# COCO-pretrained `load_from`, RepeatDataset x8, SGD lr 0.01 for batch 8,
# 8 epochs = 64 passes over the data) with the ResNeXt-101 backbone of
# `mmdet::faster_rcnn/faster-rcnn_x101-64x4d_fpn_1x_coco.py`. Differences
# from MMDet's recipe: our dataset type/loader (errors that name the file);
# nothing else. Box-only model: COCO bbox AP only (no mIoU).
_base_ = [
    'mmdet::_base_/models/faster-rcnn_r50_fpn.py',
    '../_base_/datasets/cityscapes_detection.py',
    '../_base_/schedules/schedule_cityscapes_8e.py',
    'mmdet::_base_/default_runtime.py'
]
# checkpoints that torch.load's default weights_only reads without
# cbnet_mmdet imported (DetInferencer(weights=CKPT) alone)
default_hooks = dict(
    weights_only=dict(type='CBNetWeightsOnlyCheckpointHook'))

model = dict(
    backbone=dict(
        _delete_=True,  # the base's ResNet-50 and its ImageNet init
        type='ResNeXt',
        depth=101,
        groups=64,  # 64 groups of width 4 per bottleneck ("64x4d")
        base_width=4,
        num_stages=4,
        out_indices=(0, 1, 2, 3),
        frozen_stages=1,
        norm_cfg=dict(type='BN', requires_grad=True),
        norm_eval=True,
        style='pytorch',
        # ImageNet init; superseded by `load_from` below when training
        init_cfg=dict(
            type='Pretrained', checkpoint='open-mmlab://resnext101_64x4d')),
    roi_head=dict(
        bbox_head=dict(
            num_classes=8,  # Cityscapes instance classes
            # MMDet's Cityscapes recipe: smooth L1 instead of L1
            loss_bbox=dict(type='SmoothL1Loss', beta=1.0, loss_weight=1.0))))

# lr for a batch of 8 (8 GPUs x 1 image), MMDet's Cityscapes recipe
optim_wrapper = dict(optimizer=dict(lr=0.01))

# COCO-trained Faster R-CNN X101-64x4d (box AP 42.1 on COCO val)
load_from = 'https://download.openmmlab.com/mmdetection/v2.0/faster_rcnn/faster_rcnn_x101_64x4d_fpn_1x_coco/faster_rcnn_x101_64x4d_fpn_1x_coco_20200204-833ee192.pth'  # noqa
