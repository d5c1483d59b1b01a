# What every demo-size recipe shares (the CBNet demo and the MMDet
# baselines and ablation rows it is compared with by
# tools/analysis_tools/compare_recipes.py): the generated Cityscapes-like
# data at 128x256, one MiT-B0 trunk trained from scratch, 64-channel necks
# and heads, batch 4, AdamW 1e-3, 12 epochs. Small enough to train on a
# 2-core CPU in minutes.
_base_ = [
    '../../_base_/datasets/cityscapes_instance.py',
    '../../_base_/schedules/schedule_adamw_poly_12e.py',
    '../../_base_/default_runtime.py',
]

data_root = 'data/cityscapes_like/'
width = 64  # neck/head channels (paper: 256)
img_scale = (256, 128)  # the generated demo images' size (w, h)

# The trunk of every demo-size recipe: MiT-B0 with the paper's Mish and
# CSPE, no pretrained weights (none can be downloaded here).
trunk = dict(
    type='CBNetMiT',
    arch='b0',
    act_cfg=dict(type='CBNetMish'),  # Mish, faster on CPU
    pos_encoding='cspe',
    drop_path_rate=0.0,
    out_indices=(0, 1, 2, 3),
    init_cfg=None)
trunk_channels = [32, 64, 160, 256]  # MiT-B0 stage widths

train_pipeline = [
    # MMCV's loader with errors naming a missing, corrupt or wrongly sized
    # image
    dict(type='CBNetLoadImageFromFile'),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
    dict(type='Resize', scale=img_scale, keep_ratio=True),
    dict(type='RandomFlip', prob=0.5),
    dict(type='PackDetInputs')
]
test_pipeline = [
    # the backend names an empty or missing file; MMDet's inference API
    # keeps these arguments for the loaders it puts in this one's place
    dict(type='LoadImageFromFile', backend_args=dict(backend='cbnet_image')),
    dict(type='CBNetCheckImage'),  # H x W x 3, else an error naming it
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
    # short-trained models rarely score above 0.5 (a cascade averages its
    # stages' scores), so masks from score 0.1 are painted; the paper
    # configs keep 0.5
    dict(type='CBNetInstanceMIoUMetric', ann_file=data_root + val_ann_file,
         score_thr=0.1, paint_order='score'),
]
test_evaluator = val_evaluator

# from scratch, so a larger lr than the paper's fine-tuning 6e-5; the
# backbone is from scratch too, so every part learns at the same lr (the
# paper configs give the neck and heads 10x the fine-tuned backbone's)
optim_wrapper = dict(
    optimizer=dict(lr=1e-3),
    paramwise_cfg=dict(custom_keys={
        'neck': dict(lr_mult=1.0),
        'rpn_head': dict(lr_mult=1.0),
        'roi_head': dict(lr_mult=1.0),
    }))
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
