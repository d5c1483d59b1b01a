# What `bash tools/demo.sh` trains (docs/accuracy.md "The demo on the benchmark
# preset"): the demo CBNet (the same model as
# cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py) on the benchmark's data,
# `generate_cityscapes_like.py --preset bench`: 200 train / 50 val 256x512
# images, objects from 48 px tall. The base's Resize keeps its 256x128 scale,
# so it trains and tests at half the images' side: a quarter of the benchmark's
# pixels per step, which is what fits a demo of minutes on a 2-core CPU (the
# benchmark's own budget, 600 steps at full size, takes 25-40 minutes on one
# core).
_base_ = './cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'

data_root = 'data/cityscapes_like_bench/'
val_ann_file = data_root + 'annotations/instancesonly_filtered_gtFine_val.json'
# 8 epochs of the 160 training images that hold objects (the loader drops
# the empty fifth), batch 4: 320 steps, 7 minutes on a 2-core CPU with
# nothing else running. The demo's run from a fresh clone (docs/get_started.md,
# 2026-11-26): 29.7 box AP / 18.1 mask AP / 43.0 mIoU on clear val, 4.0
# mask AP lost at beta 0.02; the full-size benchmark run stopped at 150
# steps had scored 5.2 mask AP
max_epochs = 8

train_dataloader = dict(dataset=dict(dataset=dict(data_root=data_root)))
val_dataloader = dict(dataset=dict(data_root=data_root))
test_dataloader = val_dataloader
# the base's metrics (and their settings), on this data's val split
val_evaluator = [
    dict(metric, ann_file=val_ann_file) for metric in _base_.val_evaluator
]
test_evaluator = val_evaluator

train_cfg = dict(max_epochs=max_epochs, val_interval=max_epochs)
# the base's warm-up, and its poly decay ending at this schedule's end
param_scheduler = [
    _base_.param_scheduler[0],
    dict(_base_.param_scheduler[1], end=max_epochs),
]
default_hooks = dict(checkpoint=dict(interval=max_epochs))
# one seed, so every run of the demo draws the same picture on one machine
randomness = dict(seed=0)
