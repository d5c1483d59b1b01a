import json
import os.path as osp

import pytest
import torch
from mmengine.runner import Runner

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.utils.checkpoint.files import read_checkpoint


def train_pipeline():
    return [
        dict(type='CBNetLoadPairedImageFromFile'),
        dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
        dict(type='RandomResize', scale=(96, 64), ratio_range=(0.8, 1.2),
             keep_ratio=True),
        dict(type='RandomCrop', crop_size=(48, 64)),
        dict(type='RandomFlip', prob=0.5),
        dict(type='PackDetInputs'),
    ]


@pytest.mark.slow  # ~20 s on 2 busy cores
def test_short_training_logs_loss_distill(paired_root, make_distiller_cfg,
                                          tmp_path):
    runner = Runner(
        model=make_distiller_cfg(eval_with='teacher'),
        work_dir=str(tmp_path),
        train_dataloader=dict(
            batch_size=2,
            num_workers=0,
            sampler=dict(type='DefaultSampler', shuffle=True),
            collate_fn=dict(type='pseudo_collate'),
            dataset=dict(
                type='CBNetPairedFoggyDataset',
                beta=0.02,
                data_root=paired_root,
                ann_file='instancesonly_filtered_gtFine_train.json',
                data_prefix=dict(img='leftImg8bit/train/'),
                filter_cfg=dict(filter_empty_gt=True, min_size=4),
                pipeline=train_pipeline())),
        optim_wrapper=dict(
            optimizer=dict(type='AdamW', lr=1e-4, weight_decay=0.01)),
        train_cfg=dict(by_epoch=False, max_iters=4),
        custom_hooks=[
            dict(type='CBNetTeacherEMAHook', momentum=0.99)
        ],
        default_hooks=dict(
            logger=dict(type='LoggerHook', interval=1),
            checkpoint=dict(type='CheckpointHook', interval=4,
                            by_epoch=False)),
        randomness=dict(seed=0),
        default_scope='mmdet')
    student0 = {k: v.clone() for k, v in
                runner.model.student.state_dict().items()}
    runner.train()
    distill = runner.message_hub.get_scalar('train/loss_distill')
    assert len(distill.data[0]) == 4
    assert all(v >= 0 and v == v for v in distill.data[0])
    with open(osp.join(runner.log_dir, 'vis_data', 'scalars.json')) as f:
        logged = [json.loads(line) for line in f]
    assert all('loss_distill' in row for row in logged)
    # the student trained and the teacher followed it partway (EMA)
    name = 'roi_head.mask_head.conv_logits.weight'
    student = runner.model.student.state_dict()[name]
    teacher = runner.model.teacher.state_dict()[name]
    assert not torch.equal(student, student0[name])
    assert not torch.equal(teacher, student0[name])
    assert not torch.equal(teacher, student)
    # the checkpoint carries the teacher
    ckpt = read_checkpoint(osp.join(str(tmp_path), 'iter_4.pth'))
    torch.testing.assert_close(ckpt['state_dict']['teacher.' + name],
                               teacher)
