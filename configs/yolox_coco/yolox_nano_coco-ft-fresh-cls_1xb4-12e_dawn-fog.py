# The fine-tuned YOLOX-Nano with a fresh classifier: everything from COCO
# but the 8-class head's class rows, which start from YOLOXHead's own
# initialisation (MMEngine skips the 80-row COCO tensors, their shapes do
# not fit, and the log says so): what starting the rows from COCO's
# classes of the same names is worth.
_base_ = './yolox_nano_coco-ft_1xb4-12e_dawn-fog.py'

load_from = _base_.coco_checkpoint
