# realfog_pretrained_parts (the RPN swap of the revised CBNet): its box path
# with MMDet's RPNHead in place of the Cascade RPN, on the pretrained
# MobileNetV2 with the trunk at the neck's and heads' lr (lr_mult 1)
# instead of a tenth of it; nothing else changed from
# ../cbnet-revised-box_mobilenet-v2_nasfpn-rpn_1xb2-ft_dawn-fog.py.
_base_ = '../cbnet-revised-box_mobilenet-v2_nasfpn-rpn_1xb2-ft_dawn-fog.py'
optim_wrapper = dict(
    paramwise_cfg=dict(custom_keys=dict(backbone=dict(lr_mult=1.0))))
