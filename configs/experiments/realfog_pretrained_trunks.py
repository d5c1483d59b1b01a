# Which ImageNet trunk: the stock cascade and the revised CBNet at the full
# trunk lr on MobileNetV2 (the realfog_pretrained_finetune rows, reused) and
# on EfficientNet-Lite0 (CBNetEfficientNetLite, in the plugin since the
# stock cascade on it won by more than a seed std, docs/accuracy.md).
preset = 'realfog_pretrained'
columns = ['box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
recipes = [
    dict(
        name='Cascade R-CNN, trunk lr x1',
        config='pretrained/finetune/'
        'cascade-rcnn_mobilenet-v2_fpn_1xb2-ft-trunk-lr1_dawn-fog.py'),
    dict(
        name='Cascade R-CNN, EfficientNet-Lite0, trunk lr x1',
        config='pretrained/trunks/'
        'cascade-rcnn_efficientnet-lite0_fpn_1xb2-ft-trunk-lr1_dawn-'
        'fog.py'),
    dict(
        name='CBNet revised, trunk lr x1',
        config='pretrained/finetune/'
        'cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft-trunk-'
        'lr1_dawn-fog.py'),
    dict(
        name='CBNet revised, EfficientNet-Lite0, trunk lr x1',
        config='pretrained/trunks/'
        'cbnet-revised-box_efficientnet-lite0_nasfpn-crpn_1xb2-ft-'
        'trunk-lr1_dawn-fog.py'),
]
# the row the lent GPU script's dry run trains (tools/device/run_all.py;
# --pretrained must also hold fetch_pretrained.py efficientnet_lite0's file)
device = dict(dry_row='Cascade R-CNN, EfficientNet-Lite0, trunk lr x1')
