"""Degenerate batches through the whole CBNet (demo widths): finite losses
and finite gradients in every head, never a crash."""
import numpy as np
import pytest
import torch
from mmdet.registry import MODELS
from mmdet.structures import DetDataSample
from mmdet.structures.mask import BitmapMasks
from mmengine.registry import init_default_scope
from mmengine.structures import InstanceData

import cbnet_mmdet  # noqa: F401
from tiny_configs import demo_cfg

H, W = 64, 128


def instances(boxes, labels=None):
    """``InstanceData`` with box-shaped masks, boxes in pixels (x1y1x2y2)."""
    boxes = torch.tensor(boxes, dtype=torch.float32).reshape(-1, 4)
    masks = np.zeros((len(boxes), H, W), dtype=np.uint8)
    for i, (x1, y1, x2, y2) in enumerate(boxes.long().tolist()):
        masks[i, y1:max(y2, y1 + 1), x1:max(x2, x1 + 1)] = 1
    labels = torch.zeros(len(boxes), dtype=torch.long) if labels is None \
        else torch.tensor(labels)
    return InstanceData(bboxes=boxes, labels=labels,
                        masks=BitmapMasks(masks, H, W))


def sample(gt, ignored=None):
    s = DetDataSample(metainfo=dict(
        img_shape=(H, W), ori_shape=(H, W), pad_shape=(H, W),
        scale_factor=(1., 1.), batch_input_shape=(H, W)))
    s.gt_instances = gt
    s.ignored_instances = ignored if ignored is not None else instances([])
    return s


CASES = {
    'no_instances': lambda: [sample(instances([])),
                             sample(instances([]))],
    'only_crowd': lambda: [
        sample(instances([]), ignored=instances([[10, 5, 90, 60]])),
        sample(instances([]), ignored=instances([[0, 0, W, H]]))],
    'few_pixel_instances': lambda: [
        sample(instances([[5, 5, 6, 6], [40, 30, 42, 33]], [1, 7])),
        sample(instances([[100.2, 10.7, 100.9, 11.1]], [3]))],
    'border_boxes': lambda: [
        sample(instances([[0, 0, W, H], [0, 20, 30, H], [100, 0, W, 10]],
                         [2, 2, 0])),
        sample(instances([[W - 2, H - 2, W, H]], [4]))],
    'mixed_empty_and_full': lambda: [
        sample(instances([])),
        sample(instances([[20, 10, 60, 50]], [5]))],
}


@pytest.fixture(scope='module')
def model():
    init_default_scope('mmdet')
    torch.manual_seed(0)
    cfg = demo_cfg('unused/').model
    # no ground truth added to the proposals: with only tiny objects no
    # RoI of any stage is positive
    for rcnn in cfg.train_cfg.rcnn:
        rcnn.sampler.add_gt_as_proposals = False
    return MODELS.build(cfg).train()


def loss_and_grads(model, samples):
    torch.manual_seed(0)
    imgs = [torch.randint(0, 256, (3, H, W), dtype=torch.uint8)
            for _ in samples]
    data = model.data_preprocessor(
        dict(inputs=imgs, data_samples=samples), True)
    model.zero_grad()
    losses = model(**data, mode='loss')
    total, log_vars = model.parse_losses(losses)
    total.backward()
    return log_vars, {
        n: p.grad for n, p in model.named_parameters() if p.grad is not None
    }


@pytest.mark.parametrize('case', sorted(CASES) + ['no_positive_roi'])
def test_finite_losses_and_gradients(model, case):
    if case == 'no_positive_roi':
        samples = [sample(instances([[30, 30, 31, 31]], [0])),
                   sample(instances([[90, 40, 91, 41]], [1]))]
    else:
        samples = CASES[case]()
    log_vars, grads = loss_and_grads(model, samples)
    bad = {k: float(v) for k, v in log_vars.items()
           if not torch.isfinite(v).all()}
    assert not bad, f'{case}: non-finite losses {bad}'
    # every stage's box/mask losses are present even without positives
    for key in ('s0.loss_rpn_reg', 's1.loss_rpn_cls', 's2.loss_cls',
                's2.loss_mask'):
        assert key in log_vars, (case, sorted(log_vars))
    assert grads, case
    bad = [n for n, g in grads.items() if not torch.isfinite(g).all()]
    assert not bad, f'{case}: non-finite gradients in {bad[:5]}'
    if case in ('no_instances', 'only_crowd', 'no_positive_roi'):
        # nothing to learn for boxes and masks: zero, not NaN
        assert float(log_vars['s2.loss_bbox']) == 0
        assert float(log_vars['s2.loss_mask']) == 0


def test_predict_on_blank_image(model):
    model.eval()
    s = sample(instances([]))
    data = model.data_preprocessor(
        dict(inputs=[torch.zeros(3, H, W, dtype=torch.uint8)],
             data_samples=[s]), False)
    with torch.no_grad():
        pred = model(**data, mode='predict')[0].pred_instances
    model.train()
    assert torch.isfinite(pred.bboxes).all() and torch.isfinite(
        pred.scores).all()
