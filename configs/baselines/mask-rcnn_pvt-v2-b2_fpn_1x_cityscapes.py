# Baseline (paper Tables 1-2): Mask R-CNN with a transformer backbone. The
# paper's GVT-S (Twins-SVT-S, ~24M backbone parameters) is not in MMDet; the
# closest backbone MMDet ships is PVTv2-B2 (~25M, also a pyramid vision
# transformer with spatial-reduction attention, ImageNet-1k top-1 82.0 vs
# Twins-SVT-S 81.7). MMDet's public Cityscapes Mask R-CNN recipe
# (RepeatDataset x8, 8 epochs = 64 passes, lr step after epoch 7) with the
# PVTv2-B2 backbone and optimiser of `mmdet::pvt/retinanet_pvtv2-b2_*`.
# Differences from MMDet's recipe: (1) no COCO-pretrained `load_from`
# (MMDet publishes no Mask R-CNN PVTv2 checkpoint): the backbone starts from
# ImageNet-1k, the neck and heads from scratch; (2) AdamW as PVT's recipe;
# (3) our dataset type/loader and evaluators (COCO bbox+segm AP and mIoU).
_base_ = 'mmdet::cityscapes/mask-rcnn_r50_fpn_1x_cityscapes.py'

custom_imports = dict(imports=['cbnet_mmdet'], allow_failed_imports=False)
# checkpoints that torch.load's default weights_only reads without
# cbnet_mmdet imported (DetInferencer(weights=CKPT) alone)
default_hooks = dict(
    weights_only=dict(type='CBNetWeightsOnlyCheckpointHook'))

data_root = 'data/cityscapes/'
dataset_type = 'CBNetCityscapesDataset'
val_ann_file = 'annotations/instancesonly_filtered_gtFine_val.json'

model = dict(
    backbone=dict(
        _delete_=True,
        type='PyramidVisionTransformerV2',
        embed_dims=64,  # PVTv2-B2 widths 64/128/320/512
        num_layers=[3, 4, 6, 3],  # PVTv2-B2 depths
        init_cfg=dict(
            type='Pretrained',
            checkpoint='https://github.com/whai362/PVT/'
            'releases/download/v2/pvt_v2_b2.pth')),
    neck=dict(in_channels=[64, 128, 320, 512]))

train_pipeline = [
    dict(type='LoadImageFromFile'),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
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
        ann_file=data_root + val_ann_file,
        metric=['bbox', 'segm'],
        classwise=True),
    # masks below score 0.5 are not painted; the highest score wins overlaps
    dict(
        type='CBNetInstanceMIoUMetric',
        ann_file=data_root + val_ann_file,
        score_thr=0.5,
        paint_order='score'),
]
test_evaluator = val_evaluator

# PVT's detection recipe: AdamW, lr 1e-4, weight decay 1e-4 (there for a
# batch of 16; kept for the Cityscapes batch of 8 x 1)
optim_wrapper = dict(
    optimizer=dict(
        _delete_=True, type='AdamW', lr=0.0001, weight_decay=0.0001))

load_from = None  # see (1) above
