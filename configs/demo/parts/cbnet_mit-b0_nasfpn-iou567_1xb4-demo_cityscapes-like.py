# parts set, second table: the demo CBNet with MMDet's stage IoU thresholds
# 0.5 / 0.6 / 0.7 instead of the paper's 0.5 / 0.7 / 0.9.
_base_ = [
    '../cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py',
    './_base_/parts.py',
]
model = dict(
    train_cfg=dict(rcnn=[
        dict(stage, assigner=dict(
            stage.assigner, pos_iou_thr=iou, neg_iou_thr=iou,
            min_pos_iou=iou))
        for stage, iou in zip(_base_.model.train_cfg.rcnn,
                              _base_.stock_stage_ious)
    ]))
