# The fair fight on foggy val: robust features and distillation (CBNet's
# road) against dehaze-then-detect (YOLO-Vehicle-Pro's), every detector at
# demo size. The dehazer is projects/peer_dehaze/configs/
# dehazer_attention_1xb4-600it_cityscapes-like.py, trained first with
# projects/peer_dehaze/tools/train_dehazer.py.
recipes = [
    dict(
        name='(a) CBNet, clear',
        config='demo/cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'),
    dict(
        name='(b) CBNet, foggy',
        config='demo/ablation/'
        'cbnet_mit-b0_ablation-shape-edge_1xb4-demo_foggy-cityscapes-'
        'like.py'),
    dict(
        name='(c) CBNet-DD',
        config='demo/ablation/'
        'cbnet-dd_mit-b0_ablation-shape-edge-kd_1xb4-demo_foggy-'
        'cityscapes-like.py'),
    dict(
        name='(d) dehazer + CBNet, clear',
        config='../projects/peer_dehaze/configs/'
        'cbnet_mit-b0_nasfpn_dehazer_1xb4-demo_cityscapes-like.py'),
    dict(
        name='(e) dehazer + YOLOX-Tiny, clear',
        config='../projects/peer_dehaze/configs/'
        'yolox_tiny_dehazer_1xb4-demo_cityscapes-like.py'),
]
# on the lent GPU (tools/device/run_all.py) the dehazer rows read the demo
# dehazer (carried)
device = dict(needs=[
    'work_dirs/dehaze/dehazer_attention_1xb4-600it_cityscapes-like/'
    'iter_600.pth'
])
