# CBNet with MiT-B0 (Table 1 of the paper compares the sizes).
_base_ = './cbnet_mit-b5_nasfpn-crpn_8xb1-12e_cityscapes.py'

model = dict(
    backbone=dict(
        arch='b0',
        init_cfg=dict(type='Pretrained',
                      checkpoint='checkpoints/mit_b0.pth')),
    neck=dict(in_channels=[32, 64, 160, 256]))  # MiT-B0 stage widths
