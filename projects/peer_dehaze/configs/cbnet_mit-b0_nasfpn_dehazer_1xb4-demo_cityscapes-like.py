# Dehaze-then-detect with CBNet: the demo CBNet (configs/demo/, same data,
# schedule and evaluators) behind a frozen CBNetAttentionDehazer trained
# first with
#   python projects/peer_dehaze/tools/train_dehazer.py \
#       projects/peer_dehaze/configs/dehazer_attention_1xb4-600it_cityscapes-like.py
# The detector trains on clear images, which pass through the same frozen
# dehazer, and is evaluated on clear or foggy val like the demo.
# Fair-fight entry (d). For the dark channel prior instead:
#   --cfg-options model.data_preprocessor.dehaze.type=CBNetDarkChannelPrior \
#       model.data_preprocessor.dehaze_checkpoint=None
_base_ = [
    '../../../configs/demo/cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
    './_base_/attention_dehazer.py'
]

custom_imports = dict(
    imports=['cbnet_mmdet', 'cbnet_dehaze'], allow_failed_imports=False)

model = dict(data_preprocessor=_base_.dehaze_preprocessor)
