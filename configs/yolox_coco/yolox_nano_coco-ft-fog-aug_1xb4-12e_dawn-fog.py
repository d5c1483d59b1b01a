# The fine-tuned YOLOX-Nano with rendered fog as augmentation: CBNetAddFog
# (atmospheric scattering with the image-row depth prior) right after the
# loaders, beta uniform in 0.005-0.02 1/m on half of the photos, as the
# fog_transfer set's augmentation (configs/pretrained/_base_/datasets/
# fog-transfer.py): more fog on photos that are foggy already.
_base_ = './yolox_nano_coco-ft_1xb4-12e_dawn-fog.py'

fog_aug = dict(type='CBNetAddFog', beta=(0.005, 0.02), prob=0.5)
train_dataloader = dict(dataset=dict(
    pipeline=_base_.train_dataloader.dataset.pipeline[:2] + [fog_aug] +
    _base_.train_dataloader.dataset.pipeline[2:]))
