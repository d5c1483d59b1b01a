# CBNet from a COCO-pretrained trunk: the two-stage recipes of the
# realfog_pretrained set with YOLOX-Nano's COCO trunk (CSPDarknet,
# depthwise, 32/64/128/256 channels at strides 4-32; fetch_pretrained.py
# yolox_nano) in place of the ImageNet ones, on the same DAWN fog + haze
# split, 640 px, box-only, budget and seeds. The question first: the stock
# Cascade R-CNN against CBNet-PT (a fresh FPN each), the revised CBNet
# (NAS-FPN) for the record, and the stock cascade on the pretrained PAFPN
# (YOLOX's own neck, a pooled fourth level) against the fresh FPN. Then the
# fine-tuning settings, each against the stock cascade's row (stem and
# first stage frozen, trunk at the full lr): the trunk at a tenth of the
# lr, the stem trained too, a 4x longer warm-up
# (docs/robustness.md, "CBNet from a COCO trunk").
preset = 'realfog_pretrained'
columns = ['box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
recipes = [
    dict(
        name='Cascade R-CNN, COCO trunk',
        config='coco_trunk/cascade-rcnn_yolox-nano-coco_fpn_1xb2-ft_'
        'dawn-fog.py'),
    dict(
        name='CBNet-PT, COCO trunk',
        config='coco_trunk/cbnet-pt-box_yolox-nano-coco_fpn-crpn_1xb2-ft_'
        'dawn-fog.py'),
    dict(
        name='CBNet revised, COCO trunk',
        config='coco_trunk/cbnet-revised-box_yolox-nano-coco_nasfpn-crpn_'
        '1xb2-ft_dawn-fog.py'),
    dict(
        name='Cascade R-CNN, COCO trunk + PAFPN',
        config='coco_trunk/cascade-rcnn_yolox-nano-coco_pafpn_1xb2-ft_'
        'dawn-fog.py'),
    dict(
        name='Cascade R-CNN, COCO trunk, trunk lr x0.1',
        config='coco_trunk/finetune/cascade-rcnn_yolox-nano-coco_fpn_'
        '1xb2-ft-trunk-lr0.1_dawn-fog.py'),
    dict(
        name='Cascade R-CNN, COCO trunk, stem trained',
        config='coco_trunk/finetune/cascade-rcnn_yolox-nano-coco_fpn_'
        '1xb2-ft-stem-trained_dawn-fog.py'),
    # the set's 50 warm-up iterations made 200 (of 900)
    dict(
        name='Cascade R-CNN, COCO trunk, warm-up 200',
        config='coco_trunk/cascade-rcnn_yolox-nano-coco_fpn_1xb2-ft_'
        'dawn-fog.py',
        budget=dict(warmup_iters=200)),
]
# on the lent GPU (tools/device/run_all.py) --pretrained must hold the
# converted YOLOX-Nano (fetch_pretrained.py yolox_nano); without it the dry
# run writes seeded stand-ins
device = dict(
    dry_row='Cascade R-CNN, COCO trunk',
    tiny_weights='cbnet_tools.synthetic.yolox_checkpoints:tiny_yolox_nano')
