# realfog_coco_trunk's fine-tuning settings: the stock Cascade R-CNN on
# YOLOX-Nano's COCO trunk with its stem and first stage trained too
# (nothing frozen) instead of frozen; nothing else changed.
_base_ = '../cascade-rcnn_yolox-nano-coco_fpn_1xb2-ft_dawn-fog.py'
model = dict(backbone=dict(frozen_stages=-1))
