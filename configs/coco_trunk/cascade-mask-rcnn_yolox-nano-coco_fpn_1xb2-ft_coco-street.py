# MMDet's stock Cascade Mask R-CNN of configs/pretrained/ with YOLOX-Nano's
# COCO-pretrained trunk in its place (./_base_/yolox-nano_coco_trunk.py), a
# fresh FPN, heads new: the recipes differ from configs/pretrained/'s in the
# trunk only. Fine-tuned from COCO (python
# tools/model_converters/fetch_pretrained.py yolox_nano first) on the COCO
# street subset (its converter: tools/dataset_converters/coco_street.py);
# compared by compare_recipes.py --set coco_street_coco_trunk
# (docs/accuracy.md, "Real masks from a COCO trunk"). The trunk was trained
# on COCO train2017, where some of the subset's photos (val ones among them)
# come from: its absolute AP is optimistic; the recipes, on the same trunk,
# compare fairly.
_base_ = [
    '../pretrained/cascade-mask-rcnn_mobilenet-v2_fpn_1xb2-ft_coco-street.py',
    './_base_/yolox-nano_coco_trunk.py',
]

model = _base_.coco_model
optim_wrapper = _base_.coco_optim_wrapper
