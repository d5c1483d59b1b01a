# The demo CBNet with the speed settings of the paper configs
# (docs/benchmarks.md "What changed"):
# NAS-FPN merging cells on strides 8-128 and an FPN-style stride-4 level
# (`fine_path='light'`); stage 2 of the Cascade RPN computes its deformable
# convolution with CBNetDeformConv2d (the head's default 'auto': its gather
# kernel on CPU, mmcv's on GPU; the same function as mmcv's). Compared with
# the demo CBNet (the "before") on the same data,
# budget and seeds by
#   python tools/analysis_tools/compare_recipes.py --set speed
_base_ = '../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'

model = dict(neck=dict(fine_path='light'))
