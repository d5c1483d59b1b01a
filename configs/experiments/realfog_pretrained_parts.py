# Why the revised CBNet's box path and the stock cascade differ on real fog
# (the parts method on the pretrained trunk): the two recipes differ there
# in three parts (neck, RPN, stage IoUs); each row is one of them with ONE
# part taken from the other (configs/pretrained/parts/). Every row at the
# full trunk lr (the better fine-tuning of realfog_pretrained_finetune,
# whose two rows are the whole recipes here under the same names: run in
# that set's work dir, their runs count). 'CBNet revised -NAS-FPN' has been
# shipped since as CBNet-PT (the row keeps its name: runs are keyed on it).
preset = 'realfog_pretrained'
columns = ['box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
recipes = [
    dict(
        name='Cascade R-CNN, trunk lr x1',
        config='pretrained/finetune/'
        'cascade-rcnn_mobilenet-v2_fpn_1xb2-ft-trunk-lr1_dawn-fog.py'),
    dict(
        name='Cascade R-CNN +NAS-FPN, trunk lr x1',
        config='pretrained/parts/'
        'cascade-rcnn_mobilenet-v2_nasfpn_1xb2-ft-trunk-lr1_dawn-'
        'fog.py'),
    dict(
        name='Cascade R-CNN +CRPN reg 1, trunk lr x1',
        config='pretrained/parts/'
        'cascade-rcnn_mobilenet-v2_fpn-crpn-reg1_1xb2-ft-trunk-lr1_'
        'dawn-fog.py'),
    dict(
        name='Cascade R-CNN +IoU .5/.7/.9, trunk lr x1',
        config='pretrained/parts/'
        'cascade-rcnn_mobilenet-v2_fpn-iou579_1xb2-ft-trunk-lr1_dawn-'
        'fog.py'),
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
        name='CBNet revised, RPNHead, trunk lr x1',
        config='pretrained/finetune/'
        'cbnet-revised-box_mobilenet-v2_nasfpn-rpn_1xb2-ft-trunk-lr1_'
        'dawn-fog.py'),
    dict(
        name='CBNet revised -IoU .5/.7/.9, trunk lr x1',
        config='pretrained/parts/'
        'cbnet-revised-box_mobilenet-v2_nasfpn-crpn-iou567_1xb2-ft-'
        'trunk-lr1_dawn-fog.py'),
]
# the row the lent GPU script's dry run trains (tools/device/run_all.py)
device = dict(dry_row='Cascade R-CNN +IoU .5/.7/.9, trunk lr x1')
