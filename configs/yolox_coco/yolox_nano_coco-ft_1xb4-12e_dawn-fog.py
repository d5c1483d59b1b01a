# YOLOX-Nano from COCO, fine-tuned on DAWN's real fog (fog + haze train
# split, 152 photos, 12 epochs of batches of 4): the 8-class head starts
# from COCO's rows of the same classes (rider from person). One command:
#   python tools/train.py \
#       configs/yolox_coco/yolox_nano_coco-ft_1xb4-12e_dawn-fog.py
# Results, times and the settings measured against it (resolution, EMA,
# mosaic, a fresh classifier, batch-norm statistics): docs/robustness.md,
# "A COCO-pretrained detector".
_base_ = './_base_/yolox-nano_coco_dawn-fog.py'

model = dict(bbox_head=dict(num_classes=8))
load_from = _base_.street_checkpoint
