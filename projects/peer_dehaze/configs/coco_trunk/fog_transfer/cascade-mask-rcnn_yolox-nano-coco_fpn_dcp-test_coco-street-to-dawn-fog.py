# Dehaze-then-detect at TEST time only (fog_transfer_coco set): the dark
# channel prior (He et al., the peer's training-free dehazer) in front of
# the COCO-trunk Cascade Mask R-CNN trained on clear photos. Nothing is
# trained: its row names the floor's row (weights_of, configs/experiments/
# fog_transfer_coco.py), so the harness tests the floor's checkpoint of
# each seed, on COCO street val (dehazing clear photos: its cost) and on
# DAWN's real fog val.
_base_ = [
    '../../../../../configs/coco_trunk/fog_transfer/'
    'cascade-mask-rcnn_yolox-nano-coco_fpn_'
    '1xb2-ft_coco-street-to-dawn-fog.py',
    '../../_base_/attention_dehazer.py', '../../realfog/_base_/dehazers.py'
]

custom_imports = dict(
    imports=['cbnet_mmdet', 'cbnet_dehaze'], allow_failed_imports=False)

# the dehazer in front of the detector's own input (raw 0-255 BGR)
model = dict(
    data_preprocessor=dict(
        _base_.dehaze_preprocessor, dehaze=_base_.fog_dcp,
        dehaze_checkpoint=None))
