"""CBNet-DD on pairs made on the fly: a clear-only dataset whose
pipeline adds each image's foggy twin (``CBNetAddFoggyTwin``) trains
``CBNetDistiller`` as the Foggy Cityscapes file pairs do."""
import numpy as np
import torch
from mmdet.registry import DATASETS, MODELS
from mmengine.dataset import pseudo_collate
from mmengine.optim import build_optim_wrapper

import cbnet_mmdet  # noqa: F401


def twin_pipeline():
    return [
        dict(type='LoadImageFromFile'),
        dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
        dict(type='CBNetAddFoggyTwin', beta=(0.005, 0.02)),
        dict(
            type='RandomResize',
            scale=(96, 64),
            ratio_range=(0.8, 1.2),
            keep_ratio=True),
        dict(type='RandomCrop', crop_size=(48, 64)),
        dict(type='RandomFlip', prob=0.5),
        dict(
            type='PackDetInputs',
            meta_keys=('img_id', 'img_path', 'ori_shape', 'img_shape',
                       'scale_factor', 'flip', 'flip_direction', 'fog_beta')),
    ]


def test_twin_pairs_train_the_distiller(paired_root, make_distiller_cfg):
    # the clear images and annotations only: no foggy file is read
    dataset = DATASETS.build(
        dict(
            type='CBNetCityscapesDataset',
            data_root=paired_root,
            ann_file='instancesonly_filtered_gtFine_train.json',
            data_prefix=dict(img='leftImg8bit/train/'),
            filter_cfg=dict(filter_empty_gt=True, min_size=4),
            pipeline=twin_pipeline()))
    np.random.seed(0)
    batch = pseudo_collate([dataset[0], dataset[1]])
    for inputs, sample in zip(batch['inputs'], batch['data_samples']):
        assert inputs.shape[0] == 6 and inputs.dtype == torch.uint8
        assert 0.005 <= sample.fog_beta <= 0.02
        # per pixel, the foggy half is nearer the atmospheric light (BGR)
        # than its clear twin (+1: both halves resized with rounding)
        light = 255 * torch.tensor([0.85, 0.83, 0.82]).view(3, 1, 1)
        foggy, clear = inputs[:3].float(), inputs[3:].float()
        assert ((foggy - light).abs() <= (clear - light).abs() + 1).all()
        assert (foggy - light).abs().mean() < (clear - light).abs().mean()
    torch.manual_seed(0)
    model = MODELS.build(make_distiller_cfg())
    model.init_weights()
    optim = build_optim_wrapper(model,
                                dict(optimizer=dict(type='SGD', lr=0.01)))
    before = model.student.state_dict(
    )['roi_head.mask_head.conv_logits.weight'].clone()
    log = model.train_step(batch, optim)
    assert torch.isfinite(log['loss_distill']) and log['loss_distill'] >= 0
    assert torch.isfinite(log['loss'])
    after = model.student.state_dict()['roi_head.mask_head.conv_logits.weight']
    assert not torch.equal(before, after)
