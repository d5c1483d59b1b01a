# realfog_coco_trunk's fine-tuning settings: the stock Cascade R-CNN on
# YOLOX-Nano's COCO trunk with the trunk at a tenth of the neck's and
# heads' lr (the 10:1 of configs/pretrained/'s ImageNet recipes) instead of
# the same lr; nothing else changed.
_base_ = '../cascade-rcnn_yolox-nano-coco_fpn_1xb2-ft_dawn-fog.py'
optim_wrapper = dict(
    paramwise_cfg=dict(custom_keys=dict(backbone=dict(lr_mult=0.1))))
