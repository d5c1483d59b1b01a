# Proposal recall of the three RPN heads (docs/accuracy.md).
recipes = [
    dict(
        name='CBNet CRPN',
        config='demo/rpn/crpn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'),
    dict(
        name='RPNHead',
        config='demo/rpn/rpn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'),
    dict(
        name='MMDet CascadeRPNHead',
        config='demo/rpn/'
        'mmdet-crpn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'),
]
