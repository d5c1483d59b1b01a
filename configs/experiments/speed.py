# The demo CBNet before / after the speed settings, the number of NAS-FPN
# stacks, and the test-time proposal count (the light-neck row's weights
# tested with 1000 proposals instead of 300: a test-time variant, its
# weights_of) (docs/benchmarks.md).
recipes = [
    dict(
        name='CBNet',
        config='demo/cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'),
    dict(
        name='CBNet light neck',
        config='demo/speed/'
        'cbnet_mit-b0_nasfpn-light_1xb4-demo_cityscapes-like.py'),
    dict(
        name='CBNet light neck, 3 stacks',
        config='demo/speed/'
        'cbnet_mit-b0_nasfpn-light-3stacks_1xb4-demo_cityscapes-'
        'like.py'),
    dict(
        name='CBNet light neck, 7 stacks',
        config='demo/speed/'
        'cbnet_mit-b0_nasfpn-light-7stacks_1xb4-demo_cityscapes-'
        'like.py'),
    dict(
        name='CBNet light neck, k=1000 at test',
        config='demo/speed/'
        'cbnet_mit-b0_nasfpn-light_test-k1000_1xb4-demo_cityscapes-'
        'like.py',
        weights_of='CBNet light neck'),
]
