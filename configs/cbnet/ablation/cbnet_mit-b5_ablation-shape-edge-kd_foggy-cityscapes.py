# Table 3, row 4 ("+KD"): the full loss plus clear-to-foggy distillation,
# i.e. CBNet-DD.
_base_ = '../cbnet-dd_mit-b5_nasfpn-crpn_8xb1-12e_foggy-cityscapes.py'
