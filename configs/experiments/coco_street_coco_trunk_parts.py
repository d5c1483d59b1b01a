# Which of CBNet's parts earn their place on the COCO trunk, on real masks
# (the parts method): MMDet's stock Cascade Mask R-CNN and CBNet-PT of the
# coco_street_coco_trunk set differ in three parts (the boundary-aware mask
# loss, the Cascade RPN with regression weights 1, the stage IoUs
# .5/.7/.9); each row between them is the stock recipe with ONE of them
# taken from CBNet-PT (configs/coco_trunk/parts/), and one row with the
# paper's single mask head on the last stage (CBNet-PT keeps one per stage).
# The two whole recipes keep their coco_street_coco_trunk names: run in
# that set's work dir, their runs count for both. Seed 0 of every row
# first; only rows that move more than a seed std of the stock recipe are
# carried on to seeds 1 and 2 (docs/accuracy.md, "Real masks from a COCO
# trunk").
preset = 'coco_street'
recipes = [
    dict(
        name='Cascade Mask R-CNN, COCO trunk',
        config='coco_trunk/cascade-mask-rcnn_yolox-nano-coco_fpn_1xb2-ft_'
        'coco-street.py'),
    dict(
        name='Cascade Mask R-CNN +boundary loss, COCO trunk',
        config='coco_trunk/parts/cascade-mask-rcnn_yolox-nano-coco_fpn-'
        'boundary-loss_1xb2-ft_coco-street.py'),
    dict(
        name='Cascade Mask R-CNN +CRPN reg 1, COCO trunk',
        config='coco_trunk/parts/cascade-mask-rcnn_yolox-nano-coco_fpn-'
        'crpn-reg1_1xb2-ft_coco-street.py'),
    dict(
        name='Cascade Mask R-CNN +IoU .5/.7/.9, COCO trunk',
        config='coco_trunk/parts/cascade-mask-rcnn_yolox-nano-coco_fpn-'
        'iou579_1xb2-ft_coco-street.py'),
    dict(
        name='Cascade Mask R-CNN +last-stage mask, COCO trunk',
        config='coco_trunk/parts/cascade-mask-rcnn_yolox-nano-coco_fpn-'
        'last-stage-mask_1xb2-ft_coco-street.py'),
    dict(
        name='CBNet-PT, COCO trunk',
        config='coco_trunk/cbnet-pt_yolox-nano-coco_fpn-crpn_1xb2-ft_'
        'coco-street.py'),
]
# on the lent GPU (tools/device/run_all.py) --pretrained must hold the
# converted YOLOX-Nano (fetch_pretrained.py yolox_nano); without it the dry
# run writes seeded stand-ins (the photos: the coco_street set's folder)
device = dict(
    dry_row='Cascade Mask R-CNN +last-stage mask, COCO trunk',
    tiny_weights='cbnet_tools.synthetic.yolox_checkpoints:tiny_yolox_nano')
