# Dehaze-then-detect at TEST time only (fog_transfer_coco set): the dark
# channel prior in front of the YOLOX-Nano fine-tuned on clear COCO street
# photos. Nothing is trained: its row names the clear row (weights_of), so
# the harness tests that row's checkpoint of each seed, on COCO street val
# (dehazing clear photos: its cost) and on DAWN's real fog val.
_base_ = [
    '../../../../../configs/yolox_coco/fog_transfer/'
    'yolox_nano_coco-ft_1xb4-36e_coco-street-to-dawn-fog.py',
    '../../_base_/attention_dehazer.py', '../../realfog/_base_/dehazers.py'
]

custom_imports = dict(
    imports=['cbnet_mmdet', 'cbnet_dehaze'], allow_failed_imports=False)

model = dict(
    data_preprocessor=dict(
        _base_.dehaze_preprocessor, dehaze=_base_.fog_dcp,
        dehaze_checkpoint=None))
