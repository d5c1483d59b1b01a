# Dehaze-then-detect at TEST time only (fog_transfer_coco set): the dark
# channel prior row with the peer's learned dehazer in its place
# (CBNetAttentionDehazer, frozen; trained on the generated clear/foggy
# pairs, never on real fog: train it first with
# ../../realfog/dehazer_attention_1xb4-200it_cityscapes-like.py, whose
# header has the command). Nothing is trained: the harness tests the clear
# row's checkpoint of each seed with this dehazer's weights added.
_base_ = './yolox_nano_coco-ft_dcp-test_coco-street-to-dawn-fog.py'

model = dict(
    data_preprocessor=dict(
        dehaze=dict(_base_.dehazer, _delete_=True),
        dehaze_checkpoint=_base_.fog_dehazer_checkpoint))
