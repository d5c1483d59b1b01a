# CBNet MiT-B5 trained and evaluated on Foggy Cityscapes (beta 0.02 by
# default; the beta is set in _base_/datasets/foggy_cityscapes_instance.py).
# This is also Table 3's "+shape +edge" row.
_base_ = [
    '../_base_/models/cbnet_mit-b5_nasfpn_crpn_cascade.py',
    '../_base_/datasets/foggy_cityscapes_instance.py',
    '../_base_/schedules/schedule_adamw_poly_12e.py',
    '../_base_/default_runtime.py',
]

# as the Cityscapes config: batch 8 = 8 x 1, 12 real epochs
train_dataloader = dict(batch_size=1, num_workers=2, dataset=dict(times=1))

# 1 image per GPU: SyncBN in the neck, as the Cityscapes config
model = dict(neck=dict(norm_cfg=dict(type='SyncBN', requires_grad=True)))
