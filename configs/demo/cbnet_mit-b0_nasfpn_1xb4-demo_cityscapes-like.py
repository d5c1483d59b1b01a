# The demo-size CBNet: a small CBNet (MiT-B0, narrow neck and heads)
# trained from scratch on the generated Cityscapes-like data (`--preset
# demo`, 128x256 images), small enough to train on a 2-core CPU in minutes.
# Data, schedule and trunk are shared with the demo-size baselines in this
# folder; tools/demo.sh trains this model on the benchmark preset
# (cbnet_mit-b0_nasfpn_1xb4-8e_cityscapes-like-bench.py).
_base_ = [
    '../_base_/models/cbnet_mit-b5_nasfpn_crpn_cascade.py',
    './_base_/cityscapes-like_1xb4-12e.py',
]

width = 64  # neck/head channels (paper: 256)

model = dict(
    data_preprocessor=dict(pad_size_divisor=64),
    backbone=dict(_delete_=True, **_base_.trunk),
    neck=dict(
        in_channels=_base_.trunk_channels,
        out_channels=width,
        stack_times=1,
        # the cell graph on strides 4-64, as measured in docs/accuracy.md;
        # the paper configs' faster 'light' path is the demo's `speed` row
        # (configs/demo/speed/)
        fine_path='cells'),
    rpn_head=dict(in_channels=width, feat_channels=width),
    roi_head=dict(
        bbox_roi_extractor=dict(out_channels=width),
        # a list replaces the base's whole list: take the base's stages and
        # change only their widths
        bbox_head=[
            dict(head, in_channels=width, fc_out_channels=256)
            for head in _base_.model.roi_head.bbox_head
        ],
        mask_roi_extractor=dict(out_channels=width),
        mask_head=dict(num_convs=2, in_channels=width,
                       conv_out_channels=width)),
    train_cfg=dict(
        rpn_proposal=dict(nms_pre=1000, max_per_img=300),
        # fewer sampled RoIs per image (128, base 512) for CPU speed
        rcnn=[
            dict(stage, sampler=dict(stage.sampler, num=128))
            for stage in _base_.model.train_cfg.rcnn
        ]),
    test_cfg=dict(rpn=dict(nms_pre=500, max_per_img=300)))
