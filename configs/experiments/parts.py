# What each part of CBNet is worth. First table: MMDet's stock Cascade Mask
# R-CNN on SegFormer's MiT-B0 with ONE part of the demo CBNet swapped in;
# second: the demo CBNet with ONE part taken back to the stock choice
# (configs/demo/parts/_base_/parts.py); then the candidates for a CBNet
# that beats the stock cascade (docs/accuracy.md).
recipes = [
    dict(
        name='stock (GELU, OPE)',
        config='demo/parts/'
        'cascade-mask-rcnn_mit-b0-gelu-ope_fpn_1xb4-demo_cityscapes-'
        'like.py'),
    dict(
        name='stock +Mish+CSPE',
        config='demo/'
        'cascade-mask-rcnn_mit-b0_fpn_1xb4-demo_cityscapes-like.py'),
    dict(
        name='stock +NAS-FPN',
        config='demo/parts/'
        'cascade-mask-rcnn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'),
    dict(
        name='stock +CRPN',
        config='demo/parts/'
        'cascade-mask-rcnn_mit-b0_fpn-crpn_1xb4-demo_cityscapes-'
        'like.py'),
    dict(
        name='stock +IoU .5/.7/.9',
        config='demo/parts/'
        'cascade-mask-rcnn_mit-b0_fpn-iou579_1xb4-demo_cityscapes-'
        'like.py'),
    dict(
        name='stock +last-stage mask',
        config='demo/parts/'
        'cascade-mask-rcnn_mit-b0_fpn-last-stage-mask_1xb4-demo_'
        'cityscapes-like.py'),
    dict(
        name='stock +boundary loss',
        config='demo/parts/'
        'cascade-mask-rcnn_mit-b0_fpn-boundary-loss_1xb4-demo_'
        'cityscapes-like.py'),
    dict(
        name='stock +sigmoid cls',
        config='demo/parts/'
        'cascade-mask-rcnn_mit-b0_fpn-sigmoid-cls_1xb4-demo_'
        'cityscapes-like.py'),
    dict(
        name='CBNet',
        config='demo/cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'),
    dict(
        name='CBNet -Mish+CSPE',
        config='demo/parts/'
        'cbnet_mit-b0-gelu-ope_nasfpn_1xb4-demo_cityscapes-like.py'),
    dict(
        name='CBNet -NAS-FPN',
        config='demo/parts/cbnet_mit-b0_fpn_1xb4-demo_cityscapes-like.py'),
    dict(
        name='CBNet -CRPN',
        config='demo/parts/'
        'cbnet_mit-b0_nasfpn-rpn_1xb4-demo_cityscapes-like.py'),
    dict(
        name='CBNet -IoU .5/.7/.9',
        config='demo/parts/'
        'cbnet_mit-b0_nasfpn-iou567_1xb4-demo_cityscapes-like.py'),
    dict(
        name='CBNet -last-stage mask',
        config='demo/parts/'
        'cbnet_mit-b0_nasfpn-mask-per-stage_1xb4-demo_cityscapes-'
        'like.py'),
    dict(
        name='CBNet -boundary loss',
        config='demo/parts/'
        'cbnet_mit-b0_nasfpn-bce-mask_1xb4-demo_cityscapes-like.py'),
    dict(
        name='CBNet -sigmoid cls',
        config='demo/parts/'
        'cbnet_mit-b0_nasfpn-softmax-cls_1xb4-demo_cityscapes-like.py'),
    dict(
        name='CBNet +stage masks +softmax',
        config='demo/parts/'
        'cbnet_mit-b0_nasfpn-mask-per-stage-softmax-cls_1xb4-demo_'
        'cityscapes-like.py'),
    dict(
        name='CBNet +stage masks +softmax, CRPN reg 1',
        config='demo/parts/'
        'cbnet_mit-b0_nasfpn-mask-per-stage-softmax-cls-crpn-reg1_'
        '1xb4-demo_cityscapes-like.py'),
    dict(
        name='stock +CRPN reg 1',
        config='demo/parts/'
        'cascade-mask-rcnn_mit-b0_fpn-crpn-reg1_1xb4-demo_cityscapes-'
        'like.py'),
    dict(
        name='CBNet, CRPN reg 1',
        config='demo/parts/'
        'cbnet_mit-b0_nasfpn-crpn-reg1_1xb4-demo_cityscapes-like.py'),
    dict(
        name='CBNet revised -CRPN',
        config='demo/parts/'
        'cbnet_mit-b0_nasfpn-mask-per-stage-softmax-cls-rpn_1xb4-'
        'demo_cityscapes-like.py'),
]
