# coco_street_coco_trunk_parts: MMDet's stock Cascade Mask R-CNN on YOLOX-
# Nano's COCO trunk with the paper's (and CBNet-PT's) stage IoU thresholds
# 0.5 / 0.7 / 0.9 in place of MMDet's 0.5 / 0.6 / 0.7; nothing else changed.
_base_ = [
    '../cascade-mask-rcnn_yolox-nano-coco_fpn_1xb2-ft_coco-street.py',
    '../../demo/parts/_base_/parts.py',
]
model = dict(
    train_cfg=dict(rcnn=[
        dict(stage, assigner=dict(
            stage.assigner, pos_iou_thr=iou, neg_iou_thr=iou,
            min_pos_iou=iou))
        for stage, iou in zip(_base_.model.train_cfg.rcnn,
                              _base_.cbnet_stage_ious)
    ]))
