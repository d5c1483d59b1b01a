# YOLO-Vehicle-Pro style at full size: MMDet's YOLOX-S (our Cityscapes
# baseline, configs/baselines/) behind a frozen CBNetAttentionDehazer
# trained with dehazer_attention_8xb4-20k_foggy-cityscapes.py.
# mmyolo's YOLOv8 needs mmcv < 2.1.0 (our pin is 2.1.0), hence YOLOX.
# Boxes only: box AP / AP50 (tools/analysis_tools/ap_drop.py for fog).
_base_ = [
    '../../../configs/baselines/yolox_s_8xb8-300e_cityscapes.py',
    './_base_/attention_dehazer.py'
]

custom_imports = dict(
    imports=['cbnet_mmdet', 'cbnet_dehaze'], allow_failed_imports=False)

model = dict(data_preprocessor=_base_.cityscapes_dehaze_preprocessor)
