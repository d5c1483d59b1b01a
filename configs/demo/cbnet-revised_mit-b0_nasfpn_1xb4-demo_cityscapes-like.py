# The revised CBNet at demo size (docs/accuracy.md "A CBNet that
# wins"): the demo CBNet (MiT with Mish + CSPE, NAS-FPN, the Cascade RPN,
# stage IoUs .5/.7/.9, the boundary-aware mask loss) with the three changes
# the parts tables chose, all in the parts set's row "CBNet +stage masks
# +softmax, CRPN reg 1":
# - a boundary-aware mask head on every stage (MMDet's CascadeRoIHead) instead
#   of one on the last stage ("CBNet -last-stage mask", second table);
# - softmax RoI classification instead of eq. (4)'s sigmoids ("stock
#   +sigmoid cls", first table);
# - the Cascade RPN's regression losses weighted 1, not 10 (the candidates'
#   rows).
# The paper's recipe stays configs/demo/cbnet_mit-b0_nasfpn_1xb4-demo_
# cityscapes-like.py.
_base_ = [
    './parts/cbnet_mit-b0_nasfpn-mask-per-stage-softmax-cls-crpn-reg1_'
    '1xb4-demo_cityscapes-like.py'
]
