# Real fog (DAWN, RTTS or any VOC folder as --data-root): box-only recipes
# trained on its train split, tested on its val split; learning on fog
# against dehazing in front (the dark channel prior, and the demo dehazer
# trained on the generated pairs). From scratch at demo size
# (docs/robustness.md).
recipes = [
    dict(
        name='CBNet box path',
        config='realfog/cbnet_mit-b0_nasfpn-box_1xb4-demo_voc-fog.py'),
    dict(
        name='Cascade R-CNN',
        config='realfog/cascade-rcnn_mit-b0_fpn_1xb4-demo_voc-fog.py'),
    dict(
        name='DCP + Cascade R-CNN',
        config='../projects/peer_dehaze/configs/realfog/'
        'cascade-rcnn_mit-b0_fpn_dcp_1xb4-demo_voc-fog.py'),
    dict(
        name='dehazer + Cascade R-CNN',
        config='../projects/peer_dehaze/configs/realfog/'
        'cascade-rcnn_mit-b0_fpn_dehazer_1xb4-demo_voc-fog.py'),
    dict(name='YOLOX-Tiny', config='realfog/yolox_tiny_1xb4-demo_voc-fog.py'),
    dict(
        name='DCP + YOLOX-Tiny',
        config='../projects/peer_dehaze/configs/realfog/'
        'yolox_tiny_dcp_1xb4-demo_voc-fog.py'),
    dict(
        name='dehazer + YOLOX-Tiny',
        config='../projects/peer_dehaze/configs/realfog/'
        'yolox_tiny_dehazer_1xb4-demo_voc-fog.py'),
]
