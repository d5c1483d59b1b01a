# CBNet with MiT-B4 (Table 1 of the paper compares the sizes).
_base_ = './cbnet_mit-b5_nasfpn-crpn_8xb1-12e_cityscapes.py'

model = dict(
    backbone=dict(
        arch='b4',
        init_cfg=dict(type='Pretrained',
                      checkpoint='checkpoints/mit_b4.pth')),
    neck=dict(in_channels=[64, 128, 320, 512]))  # MiT-B4 stage widths
