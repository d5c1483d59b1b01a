# Real fog on the pretrained trunk (DAWN fog + haze at 640 px): the same
# recipes box-only, YOLOX-Tiny (from scratch: no weights for its trunk) and
# dehaze-then-detect (the dark channel prior) in front of the stock
# cascade; the first two rows are the question. Then the edge model (a
# light FCOS on the same trunk at its own 320 px, its row's keep_img_scale,
# and at 640 px: what the halving costs) and CBNet-PT at this set's trunk lr
# (the fog_transfer set's in-domain ceiling for its model)
# (docs/robustness.md).
preset = 'realfog_pretrained'
columns = ['box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
recipes = [
    dict(
        name='Cascade R-CNN',
        config='pretrained/cascade-rcnn_mobilenet-v2_fpn_1xb2-ft_dawn-fog.py'),
    dict(
        name='CBNet revised',
        config='pretrained/'
        'cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft_dawn-'
        'fog.py'),
    dict(
        name='CBNet',
        config='pretrained/'
        'cbnet-box_mobilenet-v2_nasfpn-crpn_1xb2-ft_dawn-fog.py'),
    dict(
        name='CBNet revised, RPNHead',
        config='pretrained/'
        'cbnet-revised-box_mobilenet-v2_nasfpn-rpn_1xb2-ft_dawn-'
        'fog.py'),
    dict(
        name='DCP + Cascade R-CNN',
        config='../projects/peer_dehaze/configs/pretrained/'
        'cascade-rcnn_mobilenet-v2_fpn_dcp_1xb2-ft_dawn-fog.py'),
    dict(
        name='YOLOX-Tiny (scratch)',
        config='pretrained/yolox_tiny_1xb2_dawn-fog.py'),
    # its input size is part of the model: the config's 320x240, not the
    # preset's 640x480
    dict(
        name='Edge FCOS-lite, 320 px',
        config='pretrained/'
        'fcos-lite_mobilenet-v2_fpn_1xb2-ft_dawn-fog-320.py',
        keep_img_scale=True),
    dict(
        name='Edge FCOS-lite, 640 px',
        config='pretrained/fcos-lite_mobilenet-v2_fpn_1xb2-ft_dawn-fog.py'),
    dict(
        name='CBNet-PT',
        config='pretrained/'
        'cbnet-pt-box_mobilenet-v2_fpn-crpn_1xb2-ft_dawn-fog.py'),
]
# on the lent GPU (tools/device/run_all.py) --pretrained must hold the
# converted trunk (fetch_pretrained.py mobilenet_v2); the dry run trains the
# row that loads no pretrained file, two seeds at once
device = dict(dry_row='YOLOX-Tiny (scratch)', dry_seeds=[0, 1])
