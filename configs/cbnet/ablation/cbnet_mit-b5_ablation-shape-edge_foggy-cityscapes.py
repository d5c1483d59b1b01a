# Table 3, row 3 ("+shape +edge"): the full boundary-aware loss; the same
# model as the Foggy Cityscapes config, listed here so the four rows sit
# together.
_base_ = '../cbnet_mit-b5_nasfpn-crpn_8xb1-12e_foggy-cityscapes.py'
