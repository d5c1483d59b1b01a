# Trains from nothing: 0.0 box AP on DAWN's real fog at the budgets measured
# here (configs/realfog/README.md); for real photos start from
# configs/yolox_coco (COCO weights) or configs/pretrained.
# MMDet's stock Cascade R-CNN (FPN, RPNHead, softmax cascade box heads) on
# the demo's MiT-B0 trunk, widths and budget: the `arch` baseline without
# its mask head, on real fog (compare_recipes.py --set realfog).
_base_ = [
    '../demo/cascade-mask-rcnn_mit-b0_fpn_1xb4-demo_cityscapes-like.py',
    './_base_/voc-fog_box.py'
]

model = dict(
    data_preprocessor=dict(pad_mask=False),
    roi_head=dict(mask_roi_extractor=None, mask_head=None))

# the real-fog data in place of the demo's (see _base_/voc-fog_box.py)
data_root = _base_.fog_data_root
train_dataloader = dict(_delete_=True, **_base_.fog_train_dataloader)
val_dataloader = test_dataloader = dict(
    _delete_=True, **_base_.fog_test_dataloader)
val_evaluator = test_evaluator = _base_.fog_evaluator
