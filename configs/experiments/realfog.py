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
# on the lent GPU (tools/device/run_all.py): DAWN at the budget of its H100
# record; the dehazer rows read the dehazer trained on the generated pairs
# (carried); the dry run trains YOLOX-Tiny for two seeds at once
device = dict(
    preset='realfog_200it',
    dry_row='YOLOX-Tiny',
    dry_seeds=[0, 1],
    needs=['work_dirs/dehaze/dehazer_attention_1xb4-200it_cityscapes-like/'
           'iter_200.pth'])
