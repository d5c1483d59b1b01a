# The peer's learned dehazer in front of the fine-tuned COCO YOLOX-Nano at
# TEST time only: nothing is trained; the harness tests the fine-tuned
# row's checkpoint of each seed (weights_of in the realfog_coco set) with
# the frozen CBNetAttentionDehazer's weights added (trained on the
# generated clear/foggy pairs, never on real fog: train it first with
# ../realfog/dehazer_attention_1xb4-200it_cityscapes-like.py, whose header
# has the command). Training behind it, as the dark channel prior row does,
# was measured at 28 s an iteration on the project's 2-core CPU (the
# dehazer at 640x480, 4 photos a batch): about 3.5 h a seed, not run.
_base_ = './yolox_nano_coco-ft_dcp_1xb4-12e_dawn-fog.py'

model = dict(
    data_preprocessor=dict(
        dehaze=dict(_base_.dehazer, _delete_=True),
        dehaze_checkpoint=_base_.fog_dehazer_checkpoint))
