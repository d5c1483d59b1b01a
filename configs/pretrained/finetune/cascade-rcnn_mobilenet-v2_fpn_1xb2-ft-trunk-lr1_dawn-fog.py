# realfog_pretrained_finetune: MMDet's stock Cascade R-CNN on the
# pretrained MobileNetV2 with the trunk at the neck's and heads' lr (AdamW
# 2e-4, lr_mult 1) instead of a tenth of it; nothing else changed. Asks
# whether the 10:1 of configs/pretrained/_base_/mobilenet-v2_finetune.py
# holds the trunk back on DAWN's 153 training photos.
_base_ = '../cascade-rcnn_mobilenet-v2_fpn_1xb2-ft_dawn-fog.py'
optim_wrapper = dict(
    paramwise_cfg=dict(custom_keys=dict(backbone=dict(lr_mult=1.0))))
