# Trains from nothing: 0.0 box AP on DAWN's real fog at the budgets measured
# here (configs/realfog/README.md); for real photos start from
# configs/yolox_coco (COCO weights) or configs/pretrained.
# A YOLO-family detector on real fog (compare_recipes.py --set realfog):
# MMDet's YOLOX-Tiny at demo size, the one of the dehaze comparison
# without a dehazer: raw 0-255 BGR in, like MMDet's YOLOX.
_base_ = [
    '../demo/_base_/yolox_tiny_1xb4-demo_cityscapes-like.py',
    './_base_/voc-fog_box.py'
]

# the real-fog data in place of the demo's (see _base_/voc-fog_box.py)
data_root = _base_.fog_data_root
train_dataloader = dict(_delete_=True, **_base_.fog_train_dataloader)
val_dataloader = test_dataloader = dict(
    _delete_=True, **_base_.fog_test_dataloader)
val_evaluator = test_evaluator = _base_.fog_evaluator
