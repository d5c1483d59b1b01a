# MMDet's YOLOX-Tiny on real fog at the pretrained recipes' data, size and
# budget (compare_recipes.py --set realfog_pretrained): the YOLO-family row.
# From scratch: no ImageNet CSPDarknet (nor MMDet's COCO YOLOX weights)
# can be fetched on the project's machines, so this row measures what a
# detector without a pretrained trunk reaches at the same budget. Its own
# optimiser (the demo's AdamW 1e-3, every part alike) and raw 0-255 BGR
# input, like MMDet's YOLOX.
_base_ = [
    '../demo/_base_/yolox_tiny_1xb4-demo_cityscapes-like.py',
    './_base_/datasets/dawn-fog_box.py',
]

data_root = _base_.fog_data_root
train_dataloader = dict(_delete_=True, **_base_.fog_train_dataloader)
val_dataloader = test_dataloader = dict(
    _delete_=True, **_base_.fog_test_dataloader)
val_evaluator = test_evaluator = _base_.fog_evaluator
