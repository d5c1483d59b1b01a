# The fine-tuned YOLOX-Nano with MMDet's YOLOX augmentation: Mosaic (four
# photos per sample), RandomAffine (scale 0.5-1.5; YOLOX-Nano's COCO range,
# MMDet's yolox_tiny/nano config), HSV jitter, flip; no MixUp (YOLOX-Nano's
# COCO recipe has none). Output 640x480 like the other rows.
_base_ = './yolox_nano_coco-ft_1xb4-12e_dawn-fog.py'

img_scale = (640, 480)  # (w, h) of a mosaic, as the plain rows' photos
train_pipeline = [
    dict(type='Mosaic', img_scale=img_scale, pad_val=114.0),
    dict(type='RandomAffine', scaling_ratio_range=(0.5, 1.5),
         border=(-img_scale[0] // 2, -img_scale[1] // 2)),
    dict(type='YOLOXHSVRandomAug'),
    dict(type='RandomFlip', prob=0.5),
    dict(type='Resize', scale=img_scale, keep_ratio=True),
    dict(type='FilterAnnotations', min_gt_bbox_wh=(1, 1), keep_empty=False),
    dict(type='PackDetInputs')
]
train_dataloader = dict(
    # MultiImageMixDataset gives Mosaic its other photos; it has no aspect
    # ratios for AspectRatioBatchSampler (mosaics are all 640x480 anyway)
    batch_sampler=None,
    dataset=dict(
        _delete_=True,
        type='MultiImageMixDataset',
        dataset=dict(
            _base_.train_dataloader.dataset,
            pipeline=_base_.train_dataloader.dataset.pipeline[:2]),
        pipeline=train_pipeline))
