# The paper's Table 3, every row trained on foggy images (beta 0.02): the
# CE mask loss, +shape, +shape +edge, +shape +edge +KD (CBNet-DD).
recipes = [
    dict(
        name='CE',
        config='demo/ablation/'
        'cbnet_mit-b0_ablation-ce_1xb4-demo_foggy-cityscapes-like.py'),
    dict(
        name='+shape',
        config='demo/ablation/'
        'cbnet_mit-b0_ablation-shape_1xb4-demo_foggy-cityscapes-'
        'like.py'),
    dict(
        name='+shape +edge',
        config='demo/ablation/'
        'cbnet_mit-b0_ablation-shape-edge_1xb4-demo_foggy-cityscapes-'
        'like.py'),
    dict(
        name='+shape +edge +KD',
        config='demo/ablation/'
        'cbnet-dd_mit-b0_ablation-shape-edge-kd_1xb4-demo_foggy-'
        'cityscapes-like.py'),
]
