# realfog_pretrained_finetune: the revised CBNet's box path on the
# pretrained MobileNetV2 with the trunk at the neck's and heads' lr (AdamW
# 2e-4, lr_mult 1) instead of a tenth of it; nothing else changed.
_base_ = '../cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft_dawn-fog.py'
optim_wrapper = dict(
    paramwise_cfg=dict(custom_keys=dict(backbone=dict(lr_mult=1.0))))
