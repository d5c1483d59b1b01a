# realfog_pretrained_parts: the revised CBNet's box path on the pretrained
# MobileNetV2 (trunk at the full lr, as configs/pretrained/finetune/) with
# MMDet's stage IoU thresholds 0.5 / 0.6 / 0.7 in place of the paper's 0.5 /
# 0.7 / 0.9; nothing else changed.
# (the parts' values, configs/demo/parts/_base_/parts.py, come with the
# revised recipe's own bases)
_base_ = ['../finetune/cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft-'
          'trunk-lr1_dawn-fog.py']
model = dict(
    train_cfg=dict(rcnn=[
        dict(stage, assigner=dict(
            stage.assigner, pos_iou_thr=iou, neg_iou_thr=iou,
            min_pos_iou=iou))
        for stage, iou in zip(_base_.model.train_cfg.rcnn,
                              _base_.stock_stage_ious)
    ]))
