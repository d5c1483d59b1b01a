# CBNet with MiT-B0 (Table 1 of the paper compares the sizes).
_base_ = './cbnet_mit-b5_nasfpn-crpn_8xb1-12e_cityscapes.py'

model = dict(
    backbone=dict(
        arch='b0',
        # mmsegmentation's ImageNet MiT-B0 (see the base's note)
        init_cfg=dict(
            type='Pretrained',
            checkpoint='https://download.openmmlab.com/mmsegmentation/v0.5/'
            'pretrain/segformer/mit_b0_20220624-7e0fe6dd.pth')),
    neck=dict(in_channels=[32, 64, 160, 256]))  # MiT-B0 stage widths
