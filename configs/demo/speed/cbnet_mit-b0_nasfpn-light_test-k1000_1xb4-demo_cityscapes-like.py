# The light-neck demo CBNet tested with the paper's k = 1000 proposals per
# image (nms_pre and max_per_img of the paper configs' test_cfg before the
# speed settings); the demo, like the paper configs now, tests with 300. Not
# trained: its row of the speed set (configs/experiments/speed.py, weights_of)
# tests the weights that the recipe below trained for each seed, so the two
# rows differ only in the test-time proposal count.
_base_ = './cbnet_mit-b0_nasfpn-light_1xb4-demo_cityscapes-like.py'

model = dict(test_cfg=dict(rpn=dict(nms_pre=1000, max_per_img=1000)))
