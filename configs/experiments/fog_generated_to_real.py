# Generated -> real: the same models trained on the generated scenes, clear
# or with their depth-rendered fog (beta 0.02), tested on generated clear /
# foggy val and on DAWN's real fog val (--transfer-root): how far rendered
# fog is from real fog (docs/robustness.md).
preset = 'fog_generated_to_real'
columns = ['box AP', 'box AP50']
recipes = [
    dict(
        name='Cascade Mask R-CNN, generated clear',
        config='pretrained/fog_transfer/'
        'cascade-mask-rcnn_mobilenet-v2_fpn_1xb4-ft_cityscapes-like-'
        'to-dawn-fog.py'),
    dict(
        name='Cascade Mask R-CNN, generated fog',
        config='pretrained/fog_transfer/'
        'cascade-mask-rcnn_mobilenet-v2_fpn_1xb4-ft_foggy-cityscapes-'
        'like-to-dawn-fog.py'),
    dict(
        name='CBNet-PT, generated clear',
        config='pretrained/fog_transfer/'
        'cbnet-pt_mobilenet-v2_fpn-crpn_1xb4-ft_cityscapes-like-to-'
        'dawn-fog.py'),
    dict(
        name='CBNet-PT, generated fog',
        config='pretrained/fog_transfer/'
        'cbnet-pt_mobilenet-v2_fpn-crpn_1xb4-ft_foggy-cityscapes-'
        'like-to-dawn-fog.py'),
]
# every run is tested on generated clear and foggy val, then on DAWN's fog
# and haze val photos as the fog_transfer set's runs are (real fog, boxes
# only; --transfer-root, the preset's, moves the folder)
transfer_test = dict(condition='real fog', data_root='data/dawn_fog/',
                     split='val', val_fraction=0.3, split_seed=0)
# the row the lent GPU script's dry run trains (tools/device/run_all.py)
device = dict(dry_row='Cascade Mask R-CNN, generated clear')
