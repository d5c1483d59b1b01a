# Baseline (paper Tables 1-2): Faster R-CNN, ResNeXt-101 (64x4d) FPN, on the
# 8-class Cityscapes data. MMDet's public Cityscapes recipe (its R50 config:
# COCO-pretrained `load_from`, RepeatDataset x8, SGD lr 0.01 for batch 8,
# 8 epochs = 64 passes over the data) with the ResNeXt-101 backbone of
# `mmdet::faster_rcnn/faster-rcnn_x101-64x4d_fpn_1x_coco.py`. Differences
# from MMDet's recipe: our dataset type/loader (errors that name the file);
# nothing else. Box-only model: COCO bbox AP only (no mIoU).
_base_ = 'mmdet::cityscapes/faster-rcnn_r50_fpn_1x_cityscapes.py'

custom_imports = dict(imports=['cbnet_mmdet'], allow_failed_imports=False)
# checkpoints that torch.load's default weights_only reads without
# cbnet_mmdet imported (DetInferencer(weights=CKPT) alone)
default_hooks = dict(
    weights_only=dict(type='CBNetWeightsOnlyCheckpointHook'))

data_root = 'data/cityscapes/'
dataset_type = 'CBNetCityscapesDataset'

model = dict(
    backbone=dict(
        _delete_=True,  # the base's ResNet-50 has init_cfg=None
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
            type='Pretrained', checkpoint='open-mmlab://resnext101_64x4d')))

train_pipeline = [
    dict(type='LoadImageFromFile'),
    dict(type='LoadAnnotations', with_bbox=True),
    # shorter side 800-1024 of the 2048x1024 images (MMDet's recipe)
    dict(
        type='RandomResize',
        scale=[(2048, 800), (2048, 1024)],
        keep_ratio=True),
    dict(type='RandomFlip', prob=0.5),
    dict(type='PackDetInputs')
]
test_pipeline = [
    # the backend names an empty or missing file; MMDet's inference API
    # keeps these arguments for the loaders it puts in this one's place
    dict(type='LoadImageFromFile', backend_args=dict(backend='cbnet_image')),
    dict(type='CBNetCheckImage'),  # H x W x 3, else an error naming it
    dict(type='Resize', scale=(2048, 1024), keep_ratio=True),
    dict(type='LoadAnnotations', with_bbox=True),
    dict(
        type='PackDetInputs',
        meta_keys=('img_id', 'img_path', 'ori_shape', 'img_shape',
                   'scale_factor'))
]
# the base wraps the training set in RepeatDataset(times=8)
train_dataloader = dict(
    dataset=dict(
        dataset=dict(
            type=dataset_type, data_root=data_root,
            pipeline=train_pipeline)))
val_dataloader = dict(
    dataset=dict(
        type=dataset_type, data_root=data_root, pipeline=test_pipeline))
test_dataloader = val_dataloader
# the base's evaluator (CocoMetric bbox on the converter's
# annotations/instancesonly_filtered_gtFine_val.json), AP per class too
val_evaluator = dict(classwise=True)
test_evaluator = val_evaluator

# COCO-trained Faster R-CNN X101-64x4d (box AP 42.1 on COCO val)
load_from = 'https://download.openmmlab.com/mmdetection/v2.0/faster_rcnn/faster_rcnn_x101_64x4d_fpn_1x_coco/faster_rcnn_x101_64x4d_fpn_1x_coco_20200204-833ee192.pth'  # noqa
