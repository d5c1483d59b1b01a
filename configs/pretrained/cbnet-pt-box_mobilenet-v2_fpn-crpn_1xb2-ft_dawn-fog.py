# CBNet-PT, CBNet for pretrained trunks (FPN in place of the revised
# CBNet's NAS-FPN, ./_base_/models/cbnet-pt_mobilenet-v2_fpn-crpn.py), box
# path on the pretrained MobileNetV2 with the trunk at a tenth of the lr
# (the realfog_pretrained set's fine-tuning; at the full lr:
# ./cbnet-pt-box_mobilenet-v2_fpn-crpn_1xb2-ft-trunk-lr1_dawn-fog.py).
# Boxes only, fine-tuned from ImageNet (python
# tools/model_converters/fetch_pretrained.py mobilenet_v2 first) on the
# train split of DAWN's fog and haze photos, tested on its val split;
# compared by compare_recipes.py --set realfog_pretrained
# (docs/robustness.md "Real fog on a pretrained trunk").
_base_ = [
    './_base_/models/cbnet-pt_mobilenet-v2_fpn-crpn.py',
    './_base_/datasets/dawn-fog_box.py',
]

model = dict(
    data_preprocessor=dict(pad_mask=False),
    roi_head=dict(mask_roi_extractor=None, mask_head=None))

# the real-fog data in place of the demo's
data_root = _base_.fog_data_root
train_dataloader = dict(_delete_=True, **_base_.fog_train_dataloader)
val_dataloader = test_dataloader = dict(
    _delete_=True, **_base_.fog_test_dataloader)
val_evaluator = test_evaluator = _base_.fog_evaluator
