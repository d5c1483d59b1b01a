# Dehaze-then-detect with the headline CBNet (MiT-B5, 12 epochs on clear
# Cityscapes) behind a frozen CBNetAttentionDehazer trained on Foggy
# Cityscapes with dehazer_attention_8xb4-20k_foggy-cityscapes.py.
# Evaluate clear and foggy with tools/analysis_tools/ap_drop.py.
_base_ = [
    '../../../configs/cbnet/cbnet_mit-b5_nasfpn-crpn_8xb1-12e_cityscapes.py',
    './_base_/attention_dehazer.py'
]

custom_imports = dict(
    imports=['cbnet_mmdet', 'cbnet_dehaze'], allow_failed_imports=False)

model = dict(data_preprocessor=_base_.cityscapes_dehaze_preprocessor)
