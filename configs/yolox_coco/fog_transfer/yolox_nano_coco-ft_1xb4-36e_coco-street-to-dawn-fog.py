# YOLOX-Nano from COCO, fine-tuned on CLEAR COCO street photos only (the
# YOLOX floor of the fog_transfer_coco set): the DAWN recipe of
# ../yolox_nano_coco-ft_1xb4-12e_dawn-fog.py (AdamW 2e-4 for batches of 4,
# batch norms in eval mode, EMA; the 8-class head from COCO's rows) on the
# COCO street subset's 71 training photos with a street object, boxes only
# (YOLOX predicts no masks), tested on COCO street val (clear) and on
# DAWN's real fog val (the set's second test set,
# configs/experiments/fog_transfer_coco.py). One command:
#   python tools/train.py configs/yolox_coco/fog_transfer/\
#       yolox_nano_coco-ft_1xb4-36e_coco-street-to-dawn-fog.py
_base_ = [
    '../yolox_nano_coco-ft_1xb4-12e_dawn-fog.py',
    '../../pretrained/_base_/datasets/coco-street_instance.py',
]

data_root = _base_.street_data_root
street_box_train_pipeline = [
    dict(t, with_mask=False) if t['type'] == 'LoadAnnotations' else t
    for t in _base_.street_train_pipeline
]
street_box_test_pipeline = [
    dict(t, with_mask=False) if t['type'] == 'LoadAnnotations' else t
    for t in _base_.street_test_pipeline
]
train_dataloader = dict(
    _delete_=True,
    **dict(_base_.street_train_dataloader, batch_size=4,
           dataset=dict(_base_.street_train_dataloader.dataset,
                        pipeline=street_box_train_pipeline)))
val_dataloader = test_dataloader = dict(
    _delete_=True,
    **dict(_base_.street_test_dataloader,
           dataset=dict(_base_.street_test_dataloader.dataset,
                        pipeline=street_box_test_pipeline)))
val_evaluator = test_evaluator = [
    dict(type='CocoMetric', metric='bbox',
         ann_file=_base_.street_data_root + _base_.street_val_ann)
]

# the coco_street budget's images seen: 36 epochs of the 71 photos (1290
# iterations of 2 there, 645 of 4 here); the schedule, validation and
# checkpoint intervals follow (the base's are computed from its 12)
max_epochs = 36
train_cfg = dict(max_epochs=max_epochs, val_interval=max_epochs)
param_scheduler = [
    dict(type='LinearLR', start_factor=0.01, by_epoch=False, begin=0,
         end=50),  # the base's 50 iterations
    dict(type='CosineAnnealingLR', T_max=max_epochs, eta_min=1e-6,
         by_epoch=True, begin=0, end=max_epochs, convert_to_iter_based=True)
]
default_hooks = dict(checkpoint=dict(interval=max_epochs))
