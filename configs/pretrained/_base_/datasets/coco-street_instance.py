# Real street photographs with instance masks: the COCO subset
# converted by tools/dataset_converters/coco_street.py (street classes
# onto the project's 8, a seeded 70/30 split stratified by whether a photo
# holds a street object; docs/accuracy.md "Real masks"). Keys prefixed
# `street_` so that this file is a second base next to a recipe; the
# recipe configs copy them over.
# real photographs: the harness tests this folder's val split as it is, as
# 'coco street', no synthetic fog densities (configs/experiments/_base_/
# presets.py, test_conditions)
street_data_root = 'data/coco_street/'
street_img_scale = (640, 480)  # (w, h): COCO's 640-px photos as they are
street_train_ann = 'annotations/instances_train.json'
street_val_ann = 'annotations/instances_val.json'
street_train_pipeline = [
    # an unreadable image, or one of another size than its annotations
    # say, is an error naming the file
    dict(type='CBNetLoadImageFromFile'),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
    dict(type='Resize', scale=street_img_scale, keep_ratio=True),
    dict(type='RandomFlip', prob=0.5),
    dict(type='PackDetInputs')
]
street_test_pipeline = [
    dict(type='LoadImageFromFile', backend_args=dict(backend='cbnet_image')),
    dict(type='CBNetCheckImage'),
    dict(type='Resize', scale=street_img_scale, keep_ratio=True),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
    dict(
        type='PackDetInputs',
        meta_keys=('img_id', 'img_path', 'ori_shape', 'img_shape',
                   'scale_factor'))
]
street_train_dataloader = dict(
    batch_size=2,
    num_workers=1,
    persistent_workers=True,
    sampler=dict(type='DefaultSampler', shuffle=True),
    batch_sampler=dict(type='AspectRatioBatchSampler'),
    dataset=dict(
        type='CBNetCityscapesDataset',
        data_root=street_data_root,
        ann_file=street_train_ann,
        data_prefix=dict(img='images/'),
        # photos without a street object teach nothing to a two-stage
        # detector's heads here; they stay in val (false positives count)
        filter_cfg=dict(filter_empty_gt=True, min_size=1),
        pipeline=street_train_pipeline))
street_test_dataloader = dict(
    batch_size=1,
    num_workers=1,
    persistent_workers=True,
    drop_last=False,
    sampler=dict(type='DefaultSampler', shuffle=False),
    dataset=dict(
        type='CBNetCityscapesDataset',
        data_root=street_data_root,
        ann_file=street_val_ann,
        data_prefix=dict(img='images/'),
        test_mode=True,
        pipeline=street_test_pipeline))
street_evaluator = [
    dict(type='CocoMetric', ann_file=street_data_root + street_val_ann,
         metric=['bbox', 'segm']),
    # the demo recipes' setting: masks from score 0.1 are painted
    dict(type='CBNetInstanceMIoUMetric',
         ann_file=street_data_root + street_val_ann, score_thr=0.1,
         paint_order='score'),
]
