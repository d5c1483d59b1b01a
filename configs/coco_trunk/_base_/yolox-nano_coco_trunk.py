# The COCO-pretrained trunk and neck of MMDet's YOLOX-Nano
# (mmdet::yolox/yolox_nano_8xb8-300e_coco.py) with Megvii's COCO weights,
# for two-stage recipes: a second base next to a full recipe, keys prefixed
# `coco_` (as ../../pretrained/_base_/mobilenet-v2_finetune.py's `mnv2_`).
# The weights, once:
#   python tools/model_converters/fetch_pretrained.py yolox_nano
# (offline: --source yolox_nano.pth or the ONNX export) writes the file
# named below into $CBNET_PRETRAINED_DIR (default ~/.cache/cbnet_mmdet/).
# The model builds without it; training without it stops with an error
# naming that command.
coco_checkpoint = ('{{$CBNET_PRETRAINED_DIR:~/.cache/cbnet_mmdet}}/'
                   'yolox-nano_coco_megvii-0.1.1rc0.pth')
coco_trunk = dict(
    type='CSPDarknet',
    # YOLOX-Nano's: depth 0.33, width 0.25, depthwise convolutions, SiLU
    deepen_factor=0.33,
    widen_factor=0.25,
    use_depthwise=True,
    # strides 4, 8, 16, 32: stage 1 (32 ch) for an FPN's finest level as
    # the ImageNet trunks give it, then YOLOX's own three outputs (64, 128,
    # 256 ch)
    out_indices=(1, 2, 3, 4),
    # An ONNX source has its batch norms folded into the convolutions
    # (each is the identity plus a bias): they stay in eval mode, their
    # affine part trains; batch statistics of 2 photos would replace the
    # identity (YOLOX-Nano itself collapsed to 0.7 box AP so)
    norm_eval=True,
    # the stem and the first stage frozen, as configs/pretrained/'s
    # ImageNet trunks: trained, the stem (a 3x3 convolution on raw 0-255
    # pixels, its weights scaled to them) drifts under AdamW and the stock
    # cascade fell from 10.7 to 2.7 box AP on real fog in the first runs
    # (./finetune/*stem-trained*, measured against this)
    frozen_stages=1,
    init_cfg=dict(type='Pretrained', checkpoint=coco_checkpoint,
                  prefix='backbone.'))
coco_channels = [32, 64, 128, 256]
# YOLOX's input: raw 0-255 BGR, no mean or std
coco_preprocessor = dict(mean=[0.0, 0.0, 0.0], std=[1.0, 1.0, 1.0],
                         bgr_to_rgb=False)
# what a recipe of configs/pretrained/ changes to run on this trunk
# (`model = _base_.coco_model`): its input, its trunk, its neck's inputs
coco_model = dict(
    data_preprocessor=coco_preprocessor,
    backbone=dict(_delete_=True, **coco_trunk),
    neck=dict(in_channels=coco_channels))
# The pretrained neck: YOLOX-Nano's PAFPN (64 channels at strides 8, 16,
# 32) and a fourth level max-pooled from its last (stride 64) for the RPN
# and the largest RoIs, no weights of its own (CBNetExtraLevels)
coco_pafpn = [
    dict(type='YOLOXPAFPN', in_channels=[64, 128, 256], out_channels=64,
         num_csp_blocks=1, use_depthwise=True,
         init_cfg=dict(type='Pretrained', checkpoint=coco_checkpoint,
                       prefix='neck.')),
    dict(type='CBNetExtraLevels', num_outs=4),
]
coco_pafpn_strides = [8, 16, 32, 64]
# the trunk's lr: the neck's and heads' (AdamW 2e-4 for batches of 2, the
# project's fine-tuning schedule), as the ImageNet trunks' better setting
# on real fog; a tenth of it is measured against it
# (./finetune/*trunk-lr0.1*). A custom key overrides the others for the
# parameters it matches.
coco_optim_wrapper = dict(
    optimizer=dict(lr=2e-4),
    paramwise_cfg=dict(custom_keys={
        'backbone': dict(lr_mult=1.0),
        'neck': dict(lr_mult=1.0),
        'rpn_head': dict(lr_mult=1.0),
        'roi_head': dict(lr_mult=1.0),
    }))
