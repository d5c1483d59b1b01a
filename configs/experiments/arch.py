# The paper's neck, RPN, RoI head and loss against MMDet's stock models on
# the same MiT-B0 trunk, widths, data and schedule (docs/accuracy.md).
recipes = [
    dict(
        name='CBNet',
        config='demo/cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'),
    dict(
        name='Cascade Mask R-CNN',
        config='demo/'
        'cascade-mask-rcnn_mit-b0_fpn_1xb4-demo_cityscapes-like.py'),
    dict(
        name='Mask R-CNN',
        config='demo/mask-rcnn_mit-b0_fpn_1xb4-demo_cityscapes-like.py'),
]
