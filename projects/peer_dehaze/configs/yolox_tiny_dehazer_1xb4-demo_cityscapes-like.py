# "YOLO-Vehicle-Pro style" dehaze-then-detect at demo size: a frozen
# CBNetAttentionDehazer in front of MMDet's YOLOX-Tiny on the CBNet demo's
# data and budget (configs/demo/_base_/yolox_tiny_1xb4-demo_cityscapes-like.py
# says why YOLOX stands in for the paper's YOLOv8). Boxes only: mask AP and
# mIoU are not reported (the harness shows '-'). Fair-fight entry (e).
_base_ = [
    '../../../configs/demo/_base_/yolox_tiny_1xb4-demo_cityscapes-like.py',
    './_base_/attention_dehazer.py'
]

custom_imports = dict(
    imports=['cbnet_mmdet', 'cbnet_dehaze'], allow_failed_imports=False)

model = dict(data_preprocessor=_base_.dehaze_preprocessor)
