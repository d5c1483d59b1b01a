# Table 3, row 3 ("+shape +edge"): the full boundary-aware loss. The model
# of the Foggy Cityscapes config, trained with the SAME pipeline as the +KD
# row (CBNet-DD), so the rows differ in the loss and the distillation only:
# CBNet-DD crops 1024x512 "to reduce memory consumption", so every row does.
# Rows 1 and 2 inherit this file.
_base_ = '../cbnet_mit-b5_nasfpn-crpn_8xb1-12e_foggy-cityscapes.py'

train_pipeline = [
    dict(type='CBNetLoadImageFromFile'),  # as the dataset base
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
    dict(
        type='RandomResize',
        scale=[(2048, 800), (2048, 1024)],
        keep_ratio=True),
    dict(type='RandomCrop', crop_size=(1024, 512)),  # (w, h), as CBNet-DD
    dict(type='RandomFlip', prob=0.5),
    dict(type='PackDetInputs')
]
train_dataloader = dict(
    dataset=dict(dataset=dict(pipeline=train_pipeline)))
