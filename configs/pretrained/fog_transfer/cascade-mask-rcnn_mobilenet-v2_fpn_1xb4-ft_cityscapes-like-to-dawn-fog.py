# Generated -> real (compare_recipes.py --set
# fog_generated_to_real): MMDet's stock Cascade Mask R-CNN on the pretrained
# MobileNetV2 (the fog_transfer rows' model), trained on the generated
# Cityscapes-like scenes (clear), tested on their clear and depth-rendered
# foggy val and on DAWN's real fog val (the set's transfer_test,
# configs/experiments/fog_generated_to_real.py).
_base_ = '../_base_/models/cascade-mask-rcnn_mobilenet-v2_fpn.py'
