# YOLO-Vehicle-Pro's dehazing module (paper III-D; CBNetAttentionDehazer,
# small default: 16 channels, 2 blocks) trained alone, supervised, on the
# generated Cityscapes-like foggy/clear pairs (all three betas), and
# evaluated by PSNR/SSIM per beta on foggy val against the clear images:
#   python projects/peer_dehaze/tools/train_dehazer.py THIS_CONFIG \
#       --data-root DIR
# Works on any dataset in the Cityscapes layout with leftImg8bit_foggy and
# converted annotations (the pairs come from CBNetPairedFoggyDataset).
_base_ = [
    '../../../configs/_base_/default_runtime.py',
    './_base_/attention_dehazer.py'
]

custom_imports = dict(
    imports=['cbnet_mmdet', 'cbnet_dehaze'], allow_failed_imports=False)

data_root = 'data/cityscapes_like/'
betas = [0.005, 0.01, 0.02]  # the released Foggy Cityscapes densities
crop_size = (128, 128)  # (w, h) training crop; the demo images are 256x128
max_iters = 600

model = dict(
    type='CBNetDehazeModel',
    dehazer=_base_.dehazer,
    objective='supervised',
    loss_l1=dict(type='L1Loss', loss_weight=1.0),
    loss_ssim=dict(type='CBNetSSIMLoss', loss_weight=1.0))

meta_keys = ('img_id', 'img_path', 'foggy_img_path', 'ori_shape',
             'img_shape')
train_pipeline = [
    # foggy (channels 0-2) and clear (3-5) stacked: one crop and flip
    dict(type='CBNetLoadPairedImageFromFile'),
    dict(type='RandomCrop', crop_size=crop_size),
    dict(type='RandomFlip', prob=0.5),
    dict(type='PackDetInputs', meta_keys=meta_keys)
]
test_pipeline = [
    dict(type='CBNetLoadPairedImageFromFile'),  # full resolution
    dict(type='PackDetInputs', meta_keys=meta_keys)
]
paired_train = dict(
    type='CBNetPairedFoggyDataset',
    data_root=data_root,
    ann_file='annotations/instancesonly_filtered_gtFine_train.json',
    data_prefix=dict(img='leftImg8bit/train/'),
    filter_cfg=dict(filter_empty_gt=False),  # images without objects too
    pipeline=train_pipeline)
paired_val = dict(
    type='CBNetPairedFoggyDataset',
    data_root=data_root,
    ann_file='annotations/instancesonly_filtered_gtFine_val.json',
    data_prefix=dict(img='leftImg8bit/val/'),
    test_mode=True,
    pipeline=test_pipeline)

train_dataloader = dict(
    batch_size=4,
    num_workers=1,
    persistent_workers=False,
    sampler=dict(type='InfiniteSampler', shuffle=True),
    dataset=dict(
        type='ConcatDataset',
        datasets=[dict(paired_train, beta=beta) for beta in betas]))
val_dataloader = dict(
    batch_size=1,
    num_workers=1,
    persistent_workers=False,
    drop_last=False,
    sampler=dict(type='DefaultSampler', shuffle=False),
    dataset=dict(
        type='ConcatDataset',
        datasets=[dict(paired_val, beta=beta) for beta in betas]))
test_dataloader = val_dataloader
val_evaluator = dict(type='CBNetDehazeMetric')
test_evaluator = val_evaluator

train_cfg = dict(
    type='IterBasedTrainLoop',
    max_iters=max_iters,
    val_interval=max_iters)
val_cfg = dict(type='ValLoop')
test_cfg = dict(type='TestLoop')
# the paper's dehazer recipe: lr 2e-4 (Adam, GAN betas), cosine decay
optim_wrapper = dict(
    type='OptimWrapper',
    optimizer=dict(type='Adam', lr=2e-4, betas=(0.5, 0.999)))
param_scheduler = [
    dict(type='LinearLR', start_factor=0.1, by_epoch=False, begin=0,
         end=50),
    dict(type='CosineAnnealingLR', by_epoch=False, begin=0, end=max_iters,
         T_max=max_iters)
]
default_hooks = dict(
    checkpoint=dict(
        by_epoch=False, interval=max_iters, max_keep_ckpts=1,
        save_best=None),
    logger=dict(interval=20))
log_processor = dict(by_epoch=False)
