# CBNet-DD (paper II.E, formula 11): the student sees the foggy image, an EMA
# teacher sees the clear image of the same scene with the SAME crop, and a
# distillation loss ties their mask-head logits on the student's RoIs.
# Evaluated on Foggy Cityscapes val (beta from the foggy dataset base).
_base_ = './cbnet_mit-b5_nasfpn-crpn_8xb1-12e_foggy-cityscapes.py'

detector = _base_.model
model = dict(
    _delete_=True,
    type='CBNetDistiller',
    detector=detector,
    # CE between teacher and student mask logits divided by a temperature
    # per RoI, the teacher's max softmax probability (<= 1: it sharpens)
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
    dict(
        type='CBNetTeacherEMAHook',
        momentum=0.999,  # teacher keeps 99.9% of itself each step
        interval=1,
        # the ablation's teacher: a CBNet checkpoint trained on clear
        # Cityscapes (configs/cbnet_cityscapes.py); None starts it as a copy
        # of the student
        teacher_checkpoint=None)
]

# The paper crops paired images "to reduce memory consumption"; a 1024x512
# crop of the 2048x1024 scene after MMDet's multi-scale resize. No
# photometric transforms: they would differ between the two halves.
paired_train_pipeline = [
    dict(type='CBNetLoadPairedImageFromFile'),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
    dict(
        type='RandomResize',
        scale=[(2048, 800), (2048, 1024)],
        keep_ratio=True),
    dict(type='RandomCrop', crop_size=(1024, 512)),  # (w, h)
    dict(type='RandomFlip', prob=0.5),
    dict(type='PackDetInputs')
]
train_dataloader = dict(
    dataset=dict(
        dataset=dict(
            _delete_=True,
            type='CBNetPairedFoggyDataset',
            beta={{_base_.beta}},
            data_root={{_base_.data_root}},
            ann_file='annotations/instancesonly_filtered_gtFine_train.json',
            data_prefix=dict(img='leftImg8bit/train/'),
            filter_cfg=dict(filter_empty_gt=True, min_size=32),
            pipeline=paired_train_pipeline)))
