# Cityscapes boxes only, 8 classes: the instance base's data, loaders and
# resizing with box annotations and the COCO box evaluator (the baselines'
# detectors without a mask head: Faster R-CNN, YOLOX). MMDet's own
# `cityscapes_detection.py` is the same data with MMDet's loader.
_base_ = './cityscapes_instance.py'

train_pipeline = [
    # as the instance base: errors naming a missing or corrupt image
    dict(type='CBNetLoadImageFromFile', backend_args={{_base_.backend_args}}),
    dict(type='LoadAnnotations', with_bbox=True),
    # multi-scale training, shorter side 800-1024 (MMDet's Cityscapes recipe)
    dict(
        type='RandomResize',
        scale=[(2048, 800), (2048, 1024)],
        keep_ratio=True),
    dict(type='RandomFlip', prob=0.5),
    dict(type='PackDetInputs')
]
test_pipeline = [
    # as the instance base: a backend that names an empty or missing file
    dict(type='LoadImageFromFile', backend_args=dict(backend='cbnet_image')),
    dict(type='CBNetCheckImage'),
    dict(type='Resize', scale=(2048, 1024), keep_ratio=True),
    dict(type='LoadAnnotations', with_bbox=True),
    dict(
        type='PackDetInputs',
        meta_keys=('img_id', 'img_path', 'ori_shape', 'img_shape',
                   'scale_factor'))
]
train_dataloader = dict(
    dataset=dict(dataset=dict(pipeline=train_pipeline)))
val_dataloader = dict(dataset=dict(pipeline=test_pipeline))
test_dataloader = val_dataloader

val_evaluator = dict(
    _delete_=True,
    type='CocoMetric',
    ann_file={{_base_.val_ann_path}},
    metric='bbox',
    classwise=True,
    backend_args={{_base_.backend_args}})
test_evaluator = val_evaluator
