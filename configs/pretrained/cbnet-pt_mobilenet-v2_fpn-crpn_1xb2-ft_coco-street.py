# CBNet-PT, CBNet for pretrained trunks (FPN in place of the revised
# CBNet's NAS-FPN, ./_base_/models/cbnet-pt_mobilenet-v2_fpn-crpn.py), with
# masks, on the pretrained MobileNetV2. Fine-tuned from ImageNet (python
# tools/model_converters/fetch_pretrained.py mobilenet_v2 first) on the
# COCO street subset (its converter: tools/dataset_converters/
# coco_street.py); compared by compare_recipes.py --set coco_street
# (docs/accuracy.md "Real masks").
_base_ = [
    './_base_/models/cbnet-pt_mobilenet-v2_fpn-crpn.py',
    './_base_/datasets/coco-street_instance.py',
]

# the street photos in place of the demo's data
data_root = _base_.street_data_root
train_dataloader = dict(_delete_=True, **_base_.street_train_dataloader)
val_dataloader = test_dataloader = dict(
    _delete_=True, **_base_.street_test_dataloader)
val_evaluator = test_evaluator = _base_.street_evaluator
