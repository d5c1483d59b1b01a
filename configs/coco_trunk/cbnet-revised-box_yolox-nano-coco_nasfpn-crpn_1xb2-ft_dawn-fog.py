# The revised CBNet (NAS-FPN) of configs/pretrained/, for the record, with
# YOLOX-Nano's COCO-pretrained trunk in its place
# (./_base_/yolox-nano_coco_trunk.py), a fresh NAS-FPN, heads new: the
# recipes differ from configs/pretrained/'s in the trunk only. Boxes only,
# fine-tuned from COCO (python tools/model_converters/fetch_pretrained.py
# yolox_nano first) on the train split of DAWN's fog and haze photos, tested
# on its val split; compared by compare_recipes.py --set realfog_coco_trunk
# (docs/robustness.md, "CBNet from a COCO trunk").
_base_ = [
    '../pretrained/cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft_dawn-fog.py',
    './_base_/yolox-nano_coco_trunk.py',
]

model = _base_.coco_model
optim_wrapper = _base_.coco_optim_wrapper
