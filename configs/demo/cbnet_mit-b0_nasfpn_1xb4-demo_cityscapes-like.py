# The demo: a small CBNet (MiT-B0, narrow neck and heads) trained from
# scratch on the generated Cityscapes-like data (tools/demo.sh makes it,
# 128x256 images), small enough to train on a 2-core CPU in minutes.
_base_ = [
    '../_base_/models/cbnet_mit-b5_nasfpn_crpn_cascade.py',
    '../_base_/datasets/cityscapes_instance.py',
    '../_base_/schedules/schedule_adamw_poly_12e.py',
    '../_base_/default_runtime.py',
]

data_root = 'data/cityscapes_like/'
width = 64  # neck/head channels (paper: 256)
img_scale = (256, 128)  # the generated demo images' size (w, h)

model = dict(
    data_preprocessor=dict(pad_size_divisor=64),
    backbone=dict(arch='b0', drop_path_rate=0.0, init_cfg=None),
    neck=dict(
        in_channels=[32, 64, 160, 256],  # MiT-B0 stage widths
        out_channels=width,
        stack_times=1),
    rpn_head=dict(in_channels=width, feat_channels=width),
    roi_head=dict(
        bbox_roi_extractor=dict(out_channels=width),
        # a list replaces the base's whole list: take the base's stages and
        # change only their widths
        bbox_head=[
            dict(head, in_channels=width, fc_out_channels=256)
            for head in _base_.model.roi_head.bbox_head
        ],
        mask_roi_extractor=dict(out_channels=width),
        mask_head=dict(num_convs=2, in_channels=width,
                       conv_out_channels=width)),
    train_cfg=dict(
        rpn_proposal=dict(nms_pre=1000, max_per_img=300),
        # fewer sampled RoIs per image (128, base 512) for CPU speed
        rcnn=[
            dict(stage, sampler=dict(stage.sampler, num=128))
            for stage in _base_.model.train_cfg.rcnn
        ]),
    test_cfg=dict(rpn=dict(nms_pre=500, max_per_img=300)))

# MMCV's loader name, which MMDet's DetInferencer and corruption benchmark
# look for; the CBNet datasets load with CBNetLoadImageFromFile (errors
# naming the file) in its place
train_pipeline = [
    dict(type='LoadImageFromFile'),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
    dict(type='Resize', scale=img_scale, keep_ratio=True),
    dict(type='RandomFlip', prob=0.5),
    dict(type='PackDetInputs')
]
test_pipeline = [
    dict(type='LoadImageFromFile'),
    dict(type='Resize', scale=img_scale, keep_ratio=True),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
    dict(
        type='PackDetInputs',
        meta_keys=('img_id', 'img_path', 'ori_shape', 'img_shape',
                   'scale_factor'))
]
val_ann_file = 'annotations/instancesonly_filtered_gtFine_val.json'
train_dataloader = dict(
    batch_size=4,
    num_workers=1,
    dataset=dict(
        times=1,
        dataset=dict(data_root=data_root, pipeline=train_pipeline)))
val_dataloader = dict(
    batch_size=1,
    num_workers=1,
    dataset=dict(data_root=data_root, pipeline=test_pipeline))
test_dataloader = val_dataloader
val_evaluator = [
    dict(type='CocoMetric', ann_file=data_root + val_ann_file,
         metric=['bbox', 'segm']),
    # the short-trained demo rarely scores above 0.5 (the cascade averages
    # three stages' softmax scores), so masks from score 0.1 are painted;
    # the paper configs keep 0.5
    dict(type='CBNetInstanceMIoUMetric', ann_file=data_root + val_ann_file,
         score_thr=0.1, paint_order='score'),
]
test_evaluator = val_evaluator

# from scratch, so a larger lr than the paper's fine-tuning 6e-5
optim_wrapper = dict(optimizer=dict(lr=1e-3))
max_epochs = 12
train_cfg = dict(max_epochs=max_epochs, val_interval=max_epochs)
param_scheduler = [
    dict(type='LinearLR', start_factor=1e-2, by_epoch=False, begin=0,
         end=50),
    dict(type='PolyLR', power=1.0, eta_min=0.0, begin=0, end=max_epochs,
         by_epoch=True, convert_to_iter_based=True),
]
default_hooks = dict(
    checkpoint=dict(interval=max_epochs, max_keep_ckpts=1, save_best=None),
    logger=dict(interval=10))
