# Baseline (paper Tables 1-2, and the reference row of the benchmarks):
# Cascade Mask R-CNN, Swin-S (patch 4, window 7) FPN, on the 8-class
# Cityscapes data. Model: `mmdet::cascade_rcnn/cascade-mask-rcnn_r50_fpn_*`
# with the Swin-S backbone and AdamW optimiser of
# `mmdet::swin/mask-rcnn_swin-s-p4-w7_*`. Data and schedule: MMDet's public
# Cityscapes recipe (RepeatDataset x8, batch 8 x 1, 8 epochs = 64 passes,
# lr step after epoch 7). Differences from MMDet's recipe: (1) no
# COCO-pretrained `load_from` (MMDet publishes no Cascade Mask R-CNN Swin
# checkpoint): the backbone starts from ImageNet-1k, the neck and heads
# from scratch; (2) AdamW as Swin's recipe; (3) our dataset type/loader and
# evaluators (COCO bbox+segm AP and mIoU).
_base_ = [
    'mmdet::_base_/models/cascade-mask-rcnn_r50_fpn.py',
    '../_base_/datasets/cityscapes_instance.py',
    '../_base_/schedules/schedule_cityscapes_8e.py',
    'mmdet::_base_/default_runtime.py'
]
# checkpoints that torch.load's default weights_only reads without
# cbnet_mmdet imported (DetInferencer(weights=CKPT) alone)
default_hooks = dict(
    weights_only=dict(type='CBNetWeightsOnlyCheckpointHook'))

num_classes = 8  # Cityscapes instance classes
pretrained = 'https://github.com/SwinTransformer/storage/releases/download/v1.0.0/swin_small_patch4_window7_224.pth'  # noqa

model = dict(
    backbone=dict(
        _delete_=True,
        type='SwinTransformer',
        embed_dims=96,
        depths=[2, 2, 18, 2],  # Swin-S
        num_heads=[3, 6, 12, 24],
        window_size=7,
        mlp_ratio=4,
        qkv_bias=True,
        qk_scale=None,
        drop_rate=0.,
        attn_drop_rate=0.,
        drop_path_rate=0.2,  # MMDet's Swin detection recipe
        patch_norm=True,
        out_indices=(0, 1, 2, 3),
        with_cp=False,
        convert_weights=True,  # official Swin checkpoint key names
        init_cfg=dict(type='Pretrained', checkpoint=pretrained)),
    neck=dict(in_channels=[96, 192, 384, 768]),  # Swin-S stage widths
    roi_head=dict(
        # (a list replaces the base's whole list: each stage is spelled out,
        # only num_classes differs from the base)
        bbox_head=[
            dict(
                type='Shared2FCBBoxHead',
                in_channels=256,
                fc_out_channels=1024,
                roi_feat_size=7,
                num_classes=num_classes,
                bbox_coder=dict(
                    type='DeltaXYWHBBoxCoder',
                    target_means=[0., 0., 0., 0.],
                    target_stds=stds),
                reg_class_agnostic=True,
                loss_cls=dict(
                    type='CrossEntropyLoss',
                    use_sigmoid=False,
                    loss_weight=1.0),
                loss_bbox=dict(type='SmoothL1Loss', beta=1.0,
                               loss_weight=1.0))
            # Cascade R-CNN's per-stage coder deviations
            for stds in ([0.1, 0.1, 0.2, 0.2], [0.05, 0.05, 0.1, 0.1],
                         [0.033, 0.033, 0.067, 0.067])
        ],
        mask_head=dict(num_classes=num_classes)))

# ---- optimiser: Swin's (MMDet's Cityscapes timing comes with the base) ----
optim_wrapper = dict(
    # no weight decay on position tables and norms (Swin's recipe)
    paramwise_cfg=dict(
        custom_keys={
            'absolute_pos_embed': dict(decay_mult=0.),
            'relative_position_bias_table': dict(decay_mult=0.),
            'norm': dict(decay_mult=0.)
        }),
    # Swin's detection lr (there for a batch of 16; kept for 8 x 1)
    optimizer=dict(
        _delete_=True,
        type='AdamW',
        lr=0.0001,
        betas=(0.9, 0.999),
        weight_decay=0.05))
auto_scale_lr = dict(enable=False, base_batch_size=8)

load_from = None  # see (1) above
