# Cityscapes instance segmentation, 8 classes (person, rider, car, truck,
# bus, train, motorcycle, bicycle): MMDet's dataset config with our dataset
# (clear errors on missing/corrupt files) and evaluators (COCO AP, mIoU and
# the official Cityscapes AP).
# Annotations: python tools/dataset_converters/cityscapes.py data/cityscapes
_base_ = 'mmdet::_base_/datasets/cityscapes_instance.py'

custom_imports = dict(imports=['cbnet_mmdet'], allow_failed_imports=False)

dataset_type = 'CBNetCityscapesDataset'
data_root = 'data/cityscapes/'
backend_args = None
val_ann_file = 'annotations/instancesonly_filtered_gtFine_val.json'
val_ann_path = data_root + val_ann_file  # what the evaluators read

train_pipeline = [
    # MMCV's loader with errors naming a missing, corrupt or wrongly sized
    # image
    dict(type='CBNetLoadImageFromFile', backend_args=backend_args),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
    # multi-scale training, shorter side 800-1024 of the 2048x1024 images
    # (MMDet's Cityscapes recipe)
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
    # full resolution
    dict(type='Resize', scale=(2048, 1024), keep_ratio=True),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
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

val_evaluator = [
    dict(
        type='CocoMetric',
        ann_file=val_ann_path,
        metric=['bbox', 'segm'],
        classwise=True,
        backend_args=backend_args),
    dict(
        type='CBNetInstanceMIoUMetric',
        ann_file=val_ann_path,
        # masks scoring below 0.5 are not painted; where masks overlap the
        # highest-scoring one is kept (see CBNetInstanceMIoUMetric)
        score_thr=0.5,
        paint_order='score',
        backend_args=backend_args),
    # the official instance AP of the Cityscapes benchmark (cityscapesScripts
    # on gtFine's *_instanceIds.png, as MMDet's own cityscapes_instance.py
    # has it; COCO-style AP differs from it), for foggy images too; results
    # in a temporary folder
    dict(type='CBNetCityScapesMetric', backend_args=backend_args),
]
test_evaluator = val_evaluator
