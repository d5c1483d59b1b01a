# The headline config, under the short name users type:
#   mim train cbnet_mmdet configs/cbnet_cityscapes.py
_base_ = './cbnet/cbnet_mit-b5_nasfpn-crpn_8xb1-12e_cityscapes.py'
