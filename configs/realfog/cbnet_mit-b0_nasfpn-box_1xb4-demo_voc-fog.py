# Trains from nothing: 0.0 box AP on DAWN's real fog at the budgets measured
# here (configs/realfog/README.md); for real photos start from
# configs/yolox_coco (COCO weights) or configs/pretrained.
# CBNet's box path on real fog (compare_recipes.py --set realfog): the demo
# CBNet (MiT-B0 trunk, NAS-FPN, Cascade RPN, three cascade box stages with
# BCE classification) without its mask head, trained on the train split of
# a VOC real-fog folder and tested on its val split (box AP only).
# Tests a checkpoint of it on data/dawn_fog/'s val split (another VOC
# folder: --cfg-options test_dataloader.dataset.data_root=DIR):
#   python tools/test.py THIS_CONFIG CHECKPOINT
# Any other detector config: tools/analysis_tools/ap_drop.py --real-fog DIR
# (docs/robustness.md, "Real fog").
_base_ = [
    '../demo/cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
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
