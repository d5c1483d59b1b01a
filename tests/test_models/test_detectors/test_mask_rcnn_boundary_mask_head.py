"""CBNetBoundaryMaskHead inside a stock MMDetection Mask R-CNN
(``StandardRoIHead``): one training step and prediction. A single-output
RoI head calls ``head(feats)`` (mask logits only), so the mask trains with
the boundary-aware loss and the edge output stays unsupervised."""
import torch
from mmdet.registry import MODELS
from mmdet.testing import demo_mm_inputs
from mmengine.config import ConfigDict
from mmengine.optim import build_optim_wrapper

import cbnet_mmdet  # noqa: F401  (registers the modules)


def test_train_step_and_predict(make_detector_cfg):
    cfg = make_detector_cfg()
    cfg['roi_head']['mask_head'].update(
        type='CBNetBoundaryMaskHead',
        loss_mask=dict(type='CBNetBoundaryAwareLoss'))
    cfg['data_preprocessor'] = dict(
        type='DetDataPreprocessor', mean=[128.] * 3, std=[64.] * 3,
        pad_size_divisor=32, pad_mask=True)
    torch.manual_seed(0)
    model = MODELS.build(ConfigDict(cfg))
    model.init_weights()
    assert type(model.roi_head).__name__ == 'StandardRoIHead'
    head = model.roi_head.mask_head
    assert type(head).__name__ == 'CBNetBoundaryMaskHead'
    data = demo_mm_inputs(2, [(3, 64, 96)] * 2, num_items=[3, 2],
                          num_classes=8, with_mask=True)
    optim = build_optim_wrapper(model, dict(optimizer=dict(type='SGD',
                                                           lr=0.1)))
    before = {n: p.detach().clone() for n, p in head.named_parameters()}
    log = model.train_step(data, optim)
    assert log['loss_mask'] > 0 and 'loss_edge' not in log
    assert all(torch.isfinite(v) for v in log.values())
    after = dict(head.named_parameters())
    for name in ('convs.0.conv.weight', 'conv_logits.weight'):
        assert not torch.equal(before[name], after[name]), name
    assert torch.equal(before['conv_edge.weight'], after['conv_edge.weight'])
    model.eval()
    with torch.no_grad():
        preds = model.test_step(data)
    for pred in preds:
        masks = pred.pred_instances.masks
        assert masks.dtype == torch.bool and masks.shape[1:] == (64, 96)
        assert len(masks) == len(pred.pred_instances.bboxes)
