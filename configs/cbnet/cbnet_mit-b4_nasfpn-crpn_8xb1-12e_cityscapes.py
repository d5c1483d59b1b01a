# CBNet with MiT-B4 (Table 1 of the paper compares the sizes).
_base_ = './cbnet_mit-b5_nasfpn-crpn_8xb1-12e_cityscapes.py'

model = dict(
    backbone=dict(
        arch='b4',
        # mmsegmentation's ImageNet MiT-B4 (see the base's note)
        init_cfg=dict(
            type='Pretrained',
            checkpoint='https://download.openmmlab.com/mmsegmentation/v0.5/'
            'pretrain/segformer/mit_b4_20220624-d588d980.pth')),
    neck=dict(in_channels=[64, 128, 320, 512]))  # MiT-B4 stage widths
