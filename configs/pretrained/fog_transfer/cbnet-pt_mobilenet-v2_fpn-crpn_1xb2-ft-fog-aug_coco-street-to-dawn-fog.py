# CBNet-PT, clear photos + synthetic fog augmentation (fog_transfer
# set): CBNetAddFog right after the loaders (the row prior sees the
# whole photo), beta uniform in 0.005-0.02 1/m on half of the images
# (../_base_/datasets/fog-transfer.py); else the floor's recipe, data, budget
# and tests.
_base_ = ('./cbnet-pt_mobilenet-v2_fpn-crpn_'
          '1xb2-ft_coco-street-to-dawn-fog.py')

train_dataloader = dict(
    dataset=dict(pipeline=_base_.street_train_pipeline[:2] +
                 [_base_.transfer_fog] + _base_.street_train_pipeline[2:]))
