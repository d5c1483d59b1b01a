# The stock Cascade R-CNN on YOLOX-Nano's COCO trunk AND its COCO neck: the
# pretrained PAFPN (strides 8, 16, 32) with a fourth, max-pooled level
# (stride 64, CBNetExtraLevels) in place of a fresh FPN (strides 4-64);
# heads new. Compared with ./cascade-rcnn_yolox-nano-coco_fpn_1xb2-ft_dawn-
# fog.py by compare_recipes.py --set realfog_coco_trunk.
_base_ = './cascade-rcnn_yolox-nano-coco_fpn_1xb2-ft_dawn-fog.py'

strides = _base_.coco_pafpn_strides
model = dict(
    # the PAFPN takes YOLOX's own three outputs
    backbone=dict(out_indices=(2, 3, 4)),
    neck=_base_.coco_pafpn,
    rpn_head=dict(
        # two anchor sizes a level (32-512 px over strides 8-64) where the
        # FPN's stride-4 level gives the stock one (32-512 over 4-64)
        anchor_generator=dict(scales=[4, 8], strides=strides)),
    roi_head=dict(bbox_roi_extractor=dict(featmap_strides=strides[:3])))
