# The dehazer on real (Foggy) Cityscapes: 256x256 crops of the 2048x1024
# pairs, 8 GPUs x 4 crops, 20k iterations (about 54 passes over the 2975
# training scenes x 3 betas at 32 crops per step).
_base_ = './dehazer_attention_1xb4-600it_cityscapes-like.py'

data_root = 'data/cityscapes/'
max_iters = 20000
train_dataloader = dict(
    batch_size=4,
    num_workers=4,
    dataset=dict(datasets=[
        dict(d, data_root=data_root, pipeline=[
            dict(type='CBNetLoadPairedImageFromFile'),
            dict(type='RandomCrop', crop_size=(256, 256)),
            dict(type='RandomFlip', prob=0.5),
            dict(type='PackDetInputs', meta_keys=_base_.meta_keys)
        ]) for d in _base_.train_dataloader.dataset.datasets
    ]))
val_dataloader = dict(dataset=dict(datasets=[
    dict(d, data_root=data_root)
    for d in _base_.val_dataloader.dataset.datasets
]))
test_dataloader = val_dataloader
train_cfg = dict(max_iters=max_iters, val_interval=max_iters)
param_scheduler = [
    dict(type='LinearLR', start_factor=0.1, by_epoch=False, begin=0,
         end=500),
    dict(type='CosineAnnealingLR', by_epoch=False, begin=0, end=max_iters,
         T_max=max_iters)
]
default_hooks = dict(checkpoint=dict(interval=max_iters),
                     logger=dict(interval=50))
