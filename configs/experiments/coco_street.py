# Real masks: the COCO street subset (tools/dataset_converters/
# coco_street.py) on an ImageNet MobileNetV2 (tools/model_converters/
# fetch_pretrained.py mobilenet_v2), the recipes at equal widths; CBNet-PT
# is the revised CBNet with FPN in place of the NAS-FPN that cost it on
# real fog (docs/accuracy.md).
preset = 'coco_street'
recipes = [
    dict(
        name='Cascade Mask R-CNN',
        config='pretrained/'
        'cascade-mask-rcnn_mobilenet-v2_fpn_1xb2-ft_coco-street.py'),
    dict(
        name='CBNet',
        config='pretrained/'
        'cbnet_mobilenet-v2_nasfpn-crpn_1xb2-ft_coco-street.py'),
    dict(
        name='CBNet revised',
        config='pretrained/'
        'cbnet-revised_mobilenet-v2_nasfpn-crpn_1xb2-ft_coco-'
        'street.py'),
    dict(
        name='CBNet revised, RPNHead',
        config='pretrained/'
        'cbnet-revised_mobilenet-v2_nasfpn-rpn_1xb2-ft_coco-street.py'),
    dict(
        name='CBNet-PT',
        config='pretrained/'
        'cbnet-pt_mobilenet-v2_fpn-crpn_1xb2-ft_coco-street.py'),
]
# the lent GPU script's dry run (tools/device/run_all.py) trains every row
device = dict(dry_row=None)
