# The neck's normalisation on real fog: the revised CBNet at the full trunk
# lr with NAS-FPN (BatchNorm, batches of 2), with FPN (the parts set's row,
# shipped since as CBNet-PT; the row keeps its name) and with NAS-FPN on
# GroupNorm; the first two are the parts set's rows under the same names
# (same work dir).
preset = 'realfog_pretrained'
columns = ['box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
recipes = [
    dict(
        name='CBNet revised, trunk lr x1',
        config='pretrained/finetune/'
        'cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft-trunk-'
        'lr1_dawn-fog.py'),
    dict(
        name='CBNet revised -NAS-FPN, trunk lr x1',
        config='pretrained/'
        'cbnet-pt-box_mobilenet-v2_fpn-crpn_1xb2-ft-trunk-lr1_dawn-'
        'fog.py'),
    dict(
        name='CBNet revised, NAS-FPN GN, trunk lr x1',
        config='pretrained/neck/'
        'cbnet-revised-box_mobilenet-v2_nasfpn-gn-crpn_1xb2-ft-trunk-'
        'lr1_dawn-fog.py'),
]
# the row the lent GPU script's dry run trains (tools/device/run_all.py)
device = dict(dry_row='CBNet revised, NAS-FPN GN, trunk lr x1')
