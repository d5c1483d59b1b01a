# The demo CBNet with the light neck (../speed/) and 3 stacks of NAS-FPN
# cells instead of the demo's 1: the stack-count row of the speed set.
# The paper does not give the depth; 7 is NAS-FPN's RetinaNet
# depth, the paper configs' default was 7 and is 3 now (docs/benchmarks.md).
_base_ = './cbnet_mit-b0_nasfpn-light_1xb4-demo_cityscapes-like.py'

model = dict(neck=dict(stack_times=3))
