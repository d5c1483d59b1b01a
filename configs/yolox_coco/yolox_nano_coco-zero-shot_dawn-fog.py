# YOLOX-Nano with Megvii's COCO weights on DAWN's real fog as it is, no
# training: the floor every real-fog recipe is read against. The model
# predicts COCO's 80 classes; CBNetClassMapMetric scores each prediction as
# the dataset class of the same name (rider from person; COCO classes that
# are no street class are dropped) before COCO AP:
#   python tools/test.py \
#       configs/yolox_coco/yolox_nano_coco-zero-shot_dawn-fog.py \
#       ~/.cache/cbnet_mmdet/yolox-nano_coco_megvii-0.1.1rc0.pth
# Any COCO-class checkpoint is scored the same way with this evaluator in
# its own config. Nothing here trains: an 80-class head fitted to the
# dataset's 8 labels would learn wrong classes, so training is left out.
_base_ = './_base_/yolox-nano_coco_dawn-fog.py'

load_from = _base_.coco_checkpoint
test_evaluator = dict(
    _delete_=True, type='CBNetClassMapMetric', source_classes='coco',
    metric=_base_.fog_evaluator[0])
val_evaluator = test_evaluator
train_dataloader = None
train_cfg = None
optim_wrapper = None
param_scheduler = None
custom_hooks = []
