# parts set, diagnostic row: the revised CBNet's recipe ("CBNet
# +stage masks +softmax, CRPN reg 1", configs/demo/cbnet-revised_*) with
# MMDet's RPNHead (and its training settings, NMS 0.7) in place of the
# Cascade RPN: does the Cascade RPN earn its place in the revised recipe?
# (In MMDet's stock cascade it costs 1.2 mask AP even with its regression
# weights at 1: docs/accuracy.md, "A CBNet that wins".)
_base_ = [
    './cbnet_mit-b0_nasfpn-mask-per-stage-softmax-cls-crpn-reg1_1xb4-demo_'
    'cityscapes-like.py',
]
model = _base_.stock_rpn_in_cbnet
