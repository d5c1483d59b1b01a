# CBNet-PT (CBNet for pretrained trunks: the revised CBNet with FPN in place
# of NAS-FPN, the best CBNet recipe on real photographs) on the
# pretrained MobileNetV2, trained on CLEAR photos only (the floor of the
# fog_transfer set): the coco_street set's recipe as it is,
# tested on COCO street val (clear) and on DAWN's real fog val (boxes: the
# set's transfer_test, configs/experiments/fog_transfer.py).
# ../_base_/datasets/fog-transfer.py holds what the other rows of the set add.
_base_ = [
    '../cbnet-pt_mobilenet-v2_fpn-crpn_1xb2-ft_coco-street.py',
    '../_base_/datasets/fog-transfer.py',
]
