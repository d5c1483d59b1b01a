# CBNet with MiT-B3 (Table 1 of the paper compares the sizes).
_base_ = './cbnet_mit-b5_nasfpn-crpn_8xb1-12e_cityscapes.py'

model = dict(
    backbone=dict(
        arch='b3',
        init_cfg=dict(type='Pretrained',
                      checkpoint='checkpoints/mit_b3.pth')),
    neck=dict(in_channels=[64, 128, 320, 512]))  # MiT-B3 stage widths
