# Real masks from a COCO-pretrained trunk: the coco_street set's mask
# recipes with YOLOX-Nano's COCO trunk (fetch_pretrained.py yolox_nano) in
# place of the ImageNet MobileNetV2, on the same COCO street split, budget
# and seeds: the stock Cascade Mask R-CNN against CBNet-PT (a fresh FPN
# each) and the revised CBNet (NAS-FPN) (docs/accuracy.md, "Real masks
# from a COCO trunk"). The trunk was trained on COCO train2017, which holds
# some of the subset's photos: absolute AP is optimistic, the rows compare
# on equal terms.
preset = 'coco_street'
recipes = [
    dict(
        name='Cascade Mask R-CNN, COCO trunk',
        config='coco_trunk/cascade-mask-rcnn_yolox-nano-coco_fpn_1xb2-ft_'
        'coco-street.py'),
    dict(
        name='CBNet-PT, COCO trunk',
        config='coco_trunk/cbnet-pt_yolox-nano-coco_fpn-crpn_1xb2-ft_'
        'coco-street.py'),
    dict(
        name='CBNet revised, COCO trunk',
        config='coco_trunk/cbnet-revised_yolox-nano-coco_nasfpn-crpn_'
        '1xb2-ft_coco-street.py'),
]
# on the lent GPU (tools/device/run_all.py) --pretrained must hold the
# converted YOLOX-Nano (fetch_pretrained.py yolox_nano); without it the dry
# run writes seeded stand-ins (the photos: the coco_street set's folder)
device = dict(
    dry_row='Cascade Mask R-CNN, COCO trunk',
    tiny_weights='cbnet_tools.synthetic.yolox_checkpoints:tiny_yolox_nano')
