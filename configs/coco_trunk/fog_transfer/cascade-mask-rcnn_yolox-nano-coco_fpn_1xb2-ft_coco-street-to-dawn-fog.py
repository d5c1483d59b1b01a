# MMDet's stock Cascade Mask R-CNN on YOLOX-Nano's COCO trunk, trained on
# CLEAR COCO street photos only (the floor of the fog_transfer_coco set):
# the coco_street_coco_trunk set's recipe as it is, tested on COCO street
# val (clear) and on DAWN's real fog val (boxes: the set's second test
# set, configs/experiments/fog_transfer_coco.py).
_base_ = [
    '../cascade-mask-rcnn_yolox-nano-coco_fpn_1xb2-ft_coco-street.py',
    '../../pretrained/_base_/datasets/fog-transfer.py',
]
