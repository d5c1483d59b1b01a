# parts set: the stock cascade (SegFormer's MiT-B0) with the paper's stage
# IoU thresholds 0.5 / 0.7 / 0.9 instead of MMDet's 0.5 / 0.6 / 0.7.
_base_ = [
    './cascade-mask-rcnn_mit-b0-gelu-ope_fpn_1xb4-demo_cityscapes-like.py'
]
model = dict(
    train_cfg=dict(rcnn=[
        dict(stage, assigner=dict(
            stage.assigner, pos_iou_thr=iou, neg_iou_thr=iou,
            min_pos_iou=iou))
        for stage, iou in zip(_base_.model.train_cfg.rcnn,
                              _base_.cbnet_stage_ious)
    ]))
