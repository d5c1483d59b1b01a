# MMDet's own YOLOX-Nano (mmdet::yolox/yolox_nano_8xb8-300e_coco.py: the
# model Megvii's COCO weights load into strictly once converted) on real
# fog: DAWN's fog and haze photos (or any VOC folder), read as the 8
# Cityscapes classes, the seeded split every real-fog recipe shares (30 %
# val, seed 0: the same 65 val photos), photos at most 640x480, boxes only
# (configs/pretrained/_base_/datasets/dawn-fog_box.py). A shared base.
# The weights, once:
#   python tools/model_converters/fetch_pretrained.py yolox_nano
# (the official yolox_nano.pth; offline: --source FILE.onnx or the .pth)
# writes both files named below into $CBNET_PRETRAINED_DIR (default
# ~/.cache/cbnet_mmdet/). Configs build without them; training or testing
# without them stops with an error naming that command.
_base_ = [
    'mmdet::yolox/yolox_nano_8xb8-300e_coco.py',
    '../../pretrained/_base_/datasets/dawn-fog_box.py',
]

custom_imports = dict(imports=['cbnet_mmdet'], allow_failed_imports=False)

pretrained_dir = '{{$CBNET_PRETRAINED_DIR:~/.cache/cbnet_mmdet}}/'
# the 80 COCO classes, as converted
coco_checkpoint = pretrained_dir + 'yolox-nano_coco_megvii-0.1.1rc0.pth'
# the same with the classifier cut to the 8 classes, each row its COCO
# class's (rider from person): fine-tuning starts from what COCO taught
street_checkpoint = (pretrained_dir +
                     'yolox-nano_coco_megvii-0.1.1rc0_to-cityscapes-8.pth')

model = dict(
    # raw 0-255 BGR as YOLOX takes it, padded with YOLOX's grey (114), not
    # black; no multi-scale batches (BatchSyncRandomResize): the photos
    # keep the one size the comparison tests at
    data_preprocessor=dict(pad_value=114, batch_augments=None),
    # score_thr 0.01 and NMS IoU 0.65: MMDet's (and Megvii's) test settings
)

data_root = _base_.fog_data_root
train_dataloader = dict(
    _delete_=True, **dict(_base_.fog_train_dataloader, batch_size=4))
val_dataloader = test_dataloader = dict(
    _delete_=True, **_base_.fog_test_dataloader)
val_evaluator = test_evaluator = _base_.fog_evaluator

# Fine-tuning from COCO on 152 photos, as measured (docs/robustness.md, "A
# COCO-pretrained detector"): AdamW at 2e-4 for batches of 4, 12 epochs, a
# short linear warm-up then cosine decay; MMDet's SGD at YOLOX's lr
# destroyed what COCO taught (1.4 box AP after 24 epochs in a probe).
# No weight decay on norms and biases, as MMDet's YOLOX.
max_epochs = 12
train_cfg = dict(max_epochs=max_epochs, val_interval=max_epochs)
optim_wrapper = dict(
    _delete_=True,
    type='OptimWrapper',
    optimizer=dict(type='AdamW', lr=2e-4, weight_decay=0.05),
    paramwise_cfg=dict(norm_decay_mult=0., bias_decay_mult=0.))
param_scheduler = [
    dict(type='LinearLR', start_factor=0.01, by_epoch=False, begin=0,
         end=50),  # a third of the first epoch (38 iterations of 4)
    dict(type='CosineAnnealingLR', T_max=max_epochs, eta_min=1e-6,
         by_epoch=True, begin=0, end=max_epochs, convert_to_iter_based=True)
]
auto_scale_lr = dict(enable=False, base_batch_size=4)

default_hooks = dict(
    checkpoint=dict(interval=max_epochs, max_keep_ckpts=1,
                    save_best=None),
    logger=dict(interval=10),
    # the project's reliability hooks (configs/_base_/default_runtime.py:
    # the first NaN loss stops training naming its images; a load_from
    # that does not fit is logged; checkpoints that torch.load's default
    # weights_only reads without cbnet_mmdet imported)
    rng_state=dict(type='CBNetRNGStateHook'),
    non_finite=dict(type='CBNetNonFiniteLossHook'),
    checkpoint_report=dict(type='CBNetCheckpointReportHook'),
    weights_only=dict(type='CBNetWeightsOnlyCheckpointHook'))
# Every batch norm in eval mode while fine-tuning: the converted ONNX
# weights are folded (each batch norm is the identity plus a bias), which
# batch statistics of 4 photos would replace (1.8 box AP in a probe,
# against 22.6 zero-shot). The EMA of the weights as MMDet's YOLOX keeps
# it (what is tested and saved). YOLOX's mode-switch hook (mosaic off for
# the last 15 of 300 epochs) and SyncNormHook do not apply here.
custom_hooks = [
    dict(type='CBNetNormEvalHook'),
    dict(type='EMAHook', ema_type='ExpMomentumEMA', momentum=0.0001,
         update_buffers=True, priority=49)
]
