# Dehaze-then-detect at TEST time only (fog_transfer set): the dark
# channel prior (He et al., the peer's training-free dehazer) in front of
# CBNet-PT trained on clear photos. Nothing is trained: its row names the
# floor's row (weights_of, configs/experiments/fog_transfer.py), so the
# harness tests the floor's checkpoint of each seed (an error naming it when
# that run is missing), on COCO street val (dehazing clear photos: its cost)
# and on DAWN's real fog val.
_base_ = [
    '../../../../../configs/pretrained/fog_transfer/'
    'cbnet-pt_mobilenet-v2_fpn-crpn_'
    '1xb2-ft_coco-street-to-dawn-fog.py',
    '../../_base_/attention_dehazer.py', '../../realfog/_base_/dehazers.py'
]

custom_imports = dict(
    imports=['cbnet_mmdet', 'cbnet_dehaze'], allow_failed_imports=False)

model = dict(
    data_preprocessor=dict(
        _base_.dehaze_preprocessor, dehaze=_base_.fog_dcp,
        dehaze_checkpoint=None))
