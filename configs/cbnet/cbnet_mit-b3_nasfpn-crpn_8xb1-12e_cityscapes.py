# CBNet with MiT-B3 (Table 1 of the paper compares the sizes).
_base_ = './cbnet_mit-b5_nasfpn-crpn_8xb1-12e_cityscapes.py'

model = dict(
    backbone=dict(
        arch='b3',
        # mmsegmentation's ImageNet MiT-B3 (see the base's note)
        init_cfg=dict(
            type='Pretrained',
            checkpoint='https://download.openmmlab.com/mmsegmentation/v0.5/'
            'pretrain/segformer/mit_b3_20220624-13b1141c.pth')),
    neck=dict(in_channels=[64, 128, 320, 512]))  # MiT-B3 stage widths
