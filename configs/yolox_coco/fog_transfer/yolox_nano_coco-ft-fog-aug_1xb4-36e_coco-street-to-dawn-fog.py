# The clear-photo YOLOX-Nano of the fog_transfer_coco set with synthetic
# fog as augmentation: CBNetAddFog right after the loaders, beta uniform in
# 0.005-0.02 1/m on half of the photos, the fog_transfer sets' augmentation
# (../../pretrained/_base_/datasets/fog-transfer.py); else the floor's
# recipe, data, budget and tests.
_base_ = [
    './yolox_nano_coco-ft_1xb4-36e_coco-street-to-dawn-fog.py',
    '../../pretrained/_base_/datasets/fog-transfer.py',
]

train_dataloader = dict(
    dataset=dict(pipeline=_base_.street_box_train_pipeline[:2] +
                 [_base_.transfer_fog] +
                 _base_.street_box_train_pipeline[2:]))
