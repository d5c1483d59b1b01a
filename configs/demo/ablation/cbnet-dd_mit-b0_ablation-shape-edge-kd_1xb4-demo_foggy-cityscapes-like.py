# Table 3 at demo size, row 4 ("+KD"): CBNet-DD. The row-3 model is the
# student and sees the foggy image (beta 0.02); an EMA teacher sees the
# clear image of the same scene; their mask logits are distilled. Same
# pipeline as rows 1-3 (the paired loader loads both images; Resize and
# RandomFlip act on both alike).
_base_ = ('./cbnet_mit-b0_ablation-shape-edge_1xb4-demo_'
          'foggy-cityscapes-like.py')

model = dict(
    _delete_=True,
    type='CBNetDistiller',
    detector=_base_.model,
    distill_loss=dict(type='CBNetDistillLoss', loss_weight=1.0),
    eval_with='student',
    # normalises the stacked foggy (channels 0-2) + clear (3-5) image
    data_preprocessor=dict(
        type='CBNetPairedDataPreprocessor',
        mean=[123.675, 116.28, 103.53],
        std=[58.395, 57.12, 57.375],
        bgr_to_rgb=True,
        pad_mask=True,
        pad_size_divisor=64))
custom_hooks = [
    # teacher starts as a copy of the student (no clear-trained checkpoint
    # at demo size) and keeps 99.9% of itself each step (the paper config)
    dict(type='CBNetTeacherEMAHook', momentum=0.999, interval=1)
]
paired_train_pipeline = [
    dict(type='CBNetLoadPairedImageFromFile'),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
    dict(type='Resize', scale=_base_.img_scale, keep_ratio=True),
    dict(type='RandomFlip', prob=0.5),
    dict(type='PackDetInputs')
]
train_dataloader = dict(
    dataset=dict(
        dataset=dict(
            _delete_=True,
            type='CBNetPairedFoggyDataset',
            beta=_base_.beta,
            data_root=_base_.data_root,
            ann_file='annotations/instancesonly_filtered_gtFine_train.json',
            data_prefix=dict(img='leftImg8bit/train/'),
            filter_cfg=dict(filter_empty_gt=True, min_size=32),
            pipeline=paired_train_pipeline)))
