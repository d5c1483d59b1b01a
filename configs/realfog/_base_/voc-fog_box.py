# Real-fog data for the box-only recipes of configs/realfog/: a
# VOC folder (DAWN's fog/haze photos, RTTS, or any folder with
# Annotations/*.xml and JPEGImages/) read by CBNetVOCFogDataset as the 8
# Cityscapes classes (motorbike -> motorcycle), split by the seeded split
# (30 % val, seed 0: the same for every recipe and seed) since DAWN ships
# none. For RTTS (PNG images): img_suffix='.png'. Boxes only: CocoMetric
# 'bbox' on ground truth taken from the dataset (no annotation file).
# Every key is prefixed `fog_` so that this file can be a second base next
# to a detector config, which defines the plain names; the recipe configs
# copy them over (see cbnet_mit-b0_nasfpn-box_1xb4-demo_voc-fog.py).
# real data: the harness tests this folder's val split as it is, as 'real
# fog', no synthetic fog densities (configs/experiments/_base_/presets.py,
# test_conditions)
fog_data_root = 'data/dawn_fog/'
# (w, h) of the resized images: DAWN's photos are mostly 1280 wide,
# 530-960 high; a fifth of 1280 keeps the CPU runs at minutes
fog_img_scale = (256, 160)
fog_dataset = dict(
    type='CBNetVOCFogDataset',
    data_root=fog_data_root,
    ann_file='',  # no image-set file: the seeded split below
    val_fraction=0.3,
    split_seed=0)
fog_train_pipeline = [
    dict(type='CBNetLoadImageFromFile'),  # errors naming the image
    dict(type='LoadAnnotations', with_bbox=True),
    dict(type='Resize', scale=fog_img_scale, keep_ratio=True),
    dict(type='RandomFlip', prob=0.5),
    dict(type='PackDetInputs')
]
fog_test_pipeline = [
    # as every shipped test pipeline: the checking backend and
    # CBNetCheckImage (an empty, missing or non-image file is an error
    # naming it, also behind MMDet's inference API)
    dict(type='LoadImageFromFile', backend_args=dict(backend='cbnet_image')),
    dict(type='CBNetCheckImage'),
    dict(type='Resize', scale=fog_img_scale, keep_ratio=True),
    dict(type='LoadAnnotations', with_bbox=True),
    dict(
        type='PackDetInputs',
        # 'instances': the ground truth CocoMetric converts (no ann_file)
        meta_keys=('img_id', 'img_path', 'ori_shape', 'img_shape',
                   'scale_factor', 'instances'))
]
fog_train_dataloader = dict(
    batch_size=4,
    num_workers=1,
    persistent_workers=True,
    sampler=dict(type='DefaultSampler', shuffle=True),
    batch_sampler=dict(type='AspectRatioBatchSampler'),
    dataset=dict(
        fog_dataset,
        split='train',
        filter_cfg=dict(filter_empty_gt=True),
        pipeline=fog_train_pipeline))
fog_test_dataloader = dict(
    batch_size=1,
    num_workers=1,
    persistent_workers=True,
    drop_last=False,
    sampler=dict(type='DefaultSampler', shuffle=False),
    dataset=dict(
        fog_dataset,
        split='val',
        test_mode=True,
        pipeline=fog_test_pipeline))
fog_evaluator = [dict(type='CocoMetric', metric='bbox')]
