# Generated -> real (issue 44 item 3, compare_recipes.py --set
# fog_generated_to_real): the revised CBNet on the pretrained MobileNetV2 (the
# fog_transfer rows' model), trained on the generated Cityscapes-like scenes
# (clear), tested on their clear and depth-rendered foggy val and on DAWN's
# real fog val (../_base_/datasets/fog-transfer.py).
_base_ = [
    '../_base_/models/cbnet-revised_mobilenet-v2_nasfpn-crpn.py',
    '../_base_/datasets/fog-transfer.py',
]
