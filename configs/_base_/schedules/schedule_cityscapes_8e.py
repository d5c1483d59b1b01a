# MMDet's public Cityscapes schedule for its Mask / Cascade R-CNN recipes
# (`mmdet::cityscapes/*_1x_cityscapes.py`): 8 epochs over the training set
# repeated 8 times (the dataset base's RepeatDataset) = 64 passes, a linear
# warm-up, the lr divided by 10 after epoch 7. The optimiser stays MMDet's
# schedule_1x SGD unless the config replaces it.
_base_ = 'mmdet::_base_/schedules/schedule_1x.py'

max_epochs = 8
train_cfg = dict(max_epochs=max_epochs)
param_scheduler = [
    dict(
        type='LinearLR', start_factor=0.001, by_epoch=False, begin=0,
        end=500),
    # MMDet's Cityscapes configs: "[7] yields higher performance than [6]"
    dict(
        type='MultiStepLR',
        begin=0,
        end=max_epochs,
        by_epoch=True,
        milestones=[7],
        gamma=0.1)
]
