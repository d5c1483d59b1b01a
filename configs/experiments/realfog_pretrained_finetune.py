# Fine-tuning settings on real fog: the two question rows with the trunk at
# the full lr instead of a tenth (configs/pretrained/finetune/); the
# reference rows keep their realfog_pretrained names, so runs of that set's
# work dir are reused.
preset = 'realfog_pretrained'
columns = ['box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
recipes = [
    dict(
        name='Cascade R-CNN',
        config='pretrained/cascade-rcnn_mobilenet-v2_fpn_1xb2-ft_dawn-fog.py'),
    dict(
        name='Cascade R-CNN, trunk lr x1',
        config='pretrained/finetune/'
        'cascade-rcnn_mobilenet-v2_fpn_1xb2-ft-trunk-lr1_dawn-fog.py'),
    dict(
        name='CBNet revised',
        config='pretrained/'
        'cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft_dawn-'
        'fog.py'),
    dict(
        name='CBNet revised, trunk lr x1',
        config='pretrained/finetune/'
        'cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft-trunk-'
        'lr1_dawn-fog.py'),
]
# the row the lent GPU script's dry run trains (tools/device/run_all.py)
device = dict(dry_row='Cascade R-CNN, trunk lr x1')
