# The peer's learned dehazer in front of the COCO YOLOX-Nano zero-shot (no
# detector training): the dark channel prior row with
# CBNetAttentionDehazer (frozen; trained on the generated clear/foggy
# pairs, never on real fog, as in the realfog set: train it first with
# ../realfog/dehazer_attention_1xb4-200it_cityscapes-like.py, whose header
# has the command).
_base_ = './yolox_nano_coco-zero-shot_dcp_dawn-fog.py'

model = dict(
    data_preprocessor=dict(
        dehaze=dict(_base_.dehazer, _delete_=True),
        dehaze_checkpoint=_base_.fog_dehazer_checkpoint))
