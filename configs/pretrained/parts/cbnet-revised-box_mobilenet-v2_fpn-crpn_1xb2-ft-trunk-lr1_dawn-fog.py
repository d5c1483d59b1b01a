# realfog_pretrained_parts: the revised CBNet's box path on the pretrained
# MobileNetV2 (trunk at the full lr, as configs/pretrained/finetune/) with
# MMDet's FPN (the stock cascade's neck, 64 channels, padding to 32) in place
# of the NAS-FPN; nothing else changed.
# (the parts' values, configs/demo/parts/_base_/parts.py, come with the
# revised recipe's own bases)
_base_ = ['../finetune/cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft-'
           'trunk-lr1_dawn-fog.py']
model = dict(
    data_preprocessor=dict(pad_size_divisor=_base_.stock_pad_size_divisor),
    neck=dict(_delete_=True,
              **dict(_base_.stock_neck, in_channels=_base_.mnv2_channels)))
