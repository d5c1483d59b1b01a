# The COCO-trunk Cascade Mask R-CNN, clear photos + synthetic fog
# augmentation (fog_transfer_coco set): CBNetAddFog right after the loaders
# (the row prior sees the whole photo), beta uniform in 0.005-0.02 1/m on
# half of the images (../../pretrained/_base_/datasets/fog-transfer.py);
# else the floor's recipe, data, budget and tests.
_base_ = ('./cascade-mask-rcnn_yolox-nano-coco_fpn_'
          '1xb2-ft_coco-street-to-dawn-fog.py')

train_dataloader = dict(
    dataset=dict(pipeline=_base_.street_train_pipeline[:2] +
                 [_base_.transfer_fog] + _base_.street_train_pipeline[2:]))
