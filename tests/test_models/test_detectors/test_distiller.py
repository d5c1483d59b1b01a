import copy
from unittest import mock

import pytest
import torch
from mmdet.models.roi_heads import StandardRoIHead
from mmdet.registry import MODELS
from mmdet.structures.bbox import bbox2roi
from mmdet.testing import demo_mm_inputs
from mmengine.optim import build_optim_wrapper

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.models.losses import CBNetDistillLoss


def paired_batch(same=False, seed=0):
    """Two 6-channel demo images with masks; ``same``: clear == foggy."""
    data = demo_mm_inputs(
        2, [(6, 64, 96)] * 2, num_items=[3, 2], num_classes=8,
        with_mask=True)
    g = torch.Generator().manual_seed(seed)
    for img in data['inputs']:
        img.copy_(torch.randint(0, 255, img.shape, generator=g))
        if same:
            img[3:] = img[:3]
    return data


def build(cfg):
    torch.manual_seed(0)
    model = MODELS.build(cfg)
    model.init_weights()
    return model


def loss_of(model, data):
    data = model.data_preprocessor(copy.deepcopy(data), True)
    return model.loss(data['inputs'], data['data_samples'])


CASCADE = 'cascade-mask-rcnn_r50_fpn.py'


@pytest.mark.parametrize('base,roi_head', [
    ('mask-rcnn_r50_fpn.py', None),
    (CASCADE, None),
    (CASCADE, 'CBNetCascadeRoIHead'),
])
def test_distill_loss_zero_for_same_model_and_input(make_distiller_cfg, base,
                                                    roi_head):
    model = build(make_distiller_cfg(base, roi_head))
    model.train()
    losses = loss_of(model, paired_batch(same=True))
    assert 'loss_distill' in losses
    assert abs(losses['loss_distill'].item()) < 1e-5
    losses = loss_of(model, paired_batch(same=False))
    assert losses['loss_distill'].item() > 1e-4
    assert any('loss_mask' in k for k in losses)


def test_gradients_reach_only_the_student(make_distiller_cfg):
    model = build(make_distiller_cfg())
    model.train()
    assert not model.teacher.training
    assert all(not p.requires_grad for p in model.teacher.parameters())
    # a different teacher: the distillation gradient is not zero
    with torch.no_grad():
        for p in model.teacher.roi_head.mask_head.parameters():
            p.add_(0.05 * torch.randn_like(p))
    losses = loss_of(model, paired_batch())
    losses['loss_distill'].backward()
    assert all(p.grad is None for p in model.teacher.parameters())
    mask_grad = model.student.roi_head.mask_head.conv_logits.weight.grad
    assert mask_grad is not None and mask_grad.abs().sum() > 0
    # (zero_init_residual zeroes the residual branches: use the shortcut)
    backbone_grad = model.student.backbone.layer2[0].downsample[0].weight.grad
    assert backbone_grad is not None and backbone_grad.abs().sum() > 0


def test_teacher_sees_clear_student_sees_foggy(make_distiller_cfg):
    """Changing only the clear half changes only the distillation loss."""
    model = build(make_distiller_cfg())
    model.train()
    data = paired_batch()
    torch.manual_seed(1)
    base = loss_of(model, data)
    for img in data['inputs']:
        img[3:] = 255 - img[3:]
    torch.manual_seed(1)
    changed = loss_of(model, data)
    for key in base:
        if key == 'loss_distill':
            assert not torch.allclose(base[key], changed[key])
        else:
            torch.testing.assert_close(base[key], changed[key])


def test_predict_with_student_or_teacher(make_distiller_cfg):
    model = build(make_distiller_cfg())
    model.eval()
    with torch.no_grad():
        for p in model.teacher.rpn_head.parameters():
            p.add_(0.1)
    data = model.data_preprocessor(paired_batch(), False)
    foggy = data['inputs'][:, :3]
    with torch.no_grad():
        for which in ('student', 'teacher'):
            model.eval_with = which
            out = model.predict(data['inputs'], data['data_samples'])
            ref = getattr(model, which).predict(foggy,
                                                data['data_samples'])
            torch.testing.assert_close(out[0].pred_instances.bboxes,
                                       ref[0].pred_instances.bboxes)
            # a plain 3-channel image works too
            out3 = model.predict(foggy, data['data_samples'])
            torch.testing.assert_close(out3[0].pred_instances.scores,
                                       ref[0].pred_instances.scores)
            feats = model.extract_feat(data['inputs'])
            torch.testing.assert_close(
                feats[0], getattr(model, which).extract_feat(foggy)[0])


def test_state_dict_holds_teacher_and_plain_checkpoints_load_to_both(
        make_distiller_cfg):
    model = build(make_distiller_cfg())
    keys = model.state_dict().keys()
    assert any(k.startswith('teacher.') for k in keys)
    plain = MODELS.build(make_distiller_cfg()['detector'])
    plain_state = {k: v + 1 if v.is_floating_point() else v
                   for k, v in plain.state_dict().items()}
    model.load_state_dict(plain_state)
    name = 'roi_head.mask_head.conv_logits.weight'
    torch.testing.assert_close(model.student.state_dict()[name],
                               plain_state[name])
    torch.testing.assert_close(model.teacher.state_dict()[name],
                               plain_state[name])


def test_bad_config_and_input(make_distiller_cfg):
    cfg = make_distiller_cfg()
    cfg['detector']['roi_head'].pop('mask_head')
    cfg['detector']['roi_head'].pop('mask_roi_extractor')
    with pytest.raises(ValueError, match='mask head'):
        MODELS.build(cfg)
    with pytest.raises(ValueError, match='eval_with'):
        MODELS.build(make_distiller_cfg(eval_with='ema'))

    # a mask head fed the box features: its RoIs cannot be read
    cfg = make_distiller_cfg()
    cfg['detector']['roi_head'].pop('mask_roi_extractor')
    with pytest.raises(TypeError, match='mask_roi_extractor'):
        MODELS.build(cfg)

    class NoMaskLossRoIHead(StandardRoIHead):  # never runs its mask head

        def loss(self, *args, **kwargs):
            return dict()

    with mock.patch.dict(MODELS.module_dict,
                         StandardRoIHead=NoMaskLossRoIHead):
        model = build(make_distiller_cfg())
    model.train()
    with pytest.raises(RuntimeError, match='NoMaskLossRoIHead ran no mask'):
        loss_of(model, paired_batch())
    model = build(make_distiller_cfg())
    data = demo_mm_inputs(1, [(3, 64, 96)], num_classes=8, with_mask=True)
    data = model.data_preprocessor(data, True)
    with pytest.raises(ValueError, match='paired inputs'):
        model.loss(data['inputs'], data['data_samples'])


def test_ddp_one_process(make_distiller_cfg, monkeypatch, free_port):
    """DDP (gloo, 1 process): teacher excluded from gradient sync."""
    import torch.distributed as dist
    from mmengine.model import MMDistributedDataParallel
    monkeypatch.setenv('MASTER_ADDR', '127.0.0.1')
    monkeypatch.setenv('MASTER_PORT', str(free_port))
    dist.init_process_group('gloo', rank=0, world_size=1)
    try:
        model = build(make_distiller_cfg())
        teacher0 = copy.deepcopy(model.teacher.state_dict())
        ddp = MMDistributedDataParallel(
            module=model, find_unused_parameters=False)
        # the parameters DDP's reducer all-reduces gradients for
        synced = {id(p) for p in ddp._build_params_for_reducer()[0]}
        assert synced == {
            id(p)
            for p in model.student.parameters() if p.requires_grad
        }
        assert not synced & {id(p) for p in model.teacher.parameters()}
        optim = build_optim_wrapper(
            ddp, dict(optimizer=dict(type='SGD', lr=0.01)))
        for step in range(2):
            log = ddp.train_step(paired_batch(seed=step), optim)
            assert 'loss_distill' in log
        assert all(p.grad is None for p in model.teacher.parameters())
        for key, value in model.teacher.state_dict().items():
            assert torch.equal(value, teacher0[key]), key
    finally:
        dist.destroy_process_group()


def test_images_without_objects(make_distiller_cfg):
    """No ground truth -> no positive RoI -> loss_distill is 0, backward
    still works."""
    model = build(make_distiller_cfg())
    model.train()
    data = demo_mm_inputs(
        2, [(6, 64, 96)] * 2, num_items=[0, 0], num_classes=8,
        with_mask=True)
    losses = loss_of(model, data)
    assert losses['loss_distill'].item() == 0
    losses['loss_distill'].backward()


def teacher_mask_logits(teacher, clear, rois):
    """The teacher's last mask head on ``rois``, computed here from its
    parts (RoI extractor + mask head), not through the distiller."""
    roi_head = teacher.roi_head
    extractor, head = roi_head.mask_roi_extractor, roi_head.mask_head
    if isinstance(head, torch.nn.ModuleList):  # MMDet's cascade: per stage
        extractor, head = extractor[-1], head[-1]
    feats = teacher.extract_feat(clear)
    return head(extractor(feats[:extractor.num_inputs], rois))


@pytest.mark.parametrize('base,roi_head', [
    ('mask-rcnn_r50_fpn.py', None),
    (CASCADE, None),
    (CASCADE, 'CBNetCascadeRoIHead'),
])
def test_loss_distill_is_distill_loss_on_recorded_rois(
        make_distiller_cfg, base, roi_head):
    """Record what the student's mask head saw (its positive RoIs of the
    last stage and its logits), run the teacher's mask head on the same RoIs
    of the clear image, and recompute ``loss_distill`` with
    ``CBNetDistillLoss`` on the ground-truth class channel."""
    model = build(make_distiller_cfg(base, roi_head))
    model.train()
    with torch.no_grad():  # a teacher that differs from the student
        for p in model.teacher.roi_head.mask_head.parameters():
            p.add_(0.05 * torch.randn_like(p))
    head = model.student.roi_head.mask_head
    if isinstance(head, torch.nn.ModuleList):
        head = head[-1]
    calls = []
    original = head.loss_and_target

    def spy(mask_preds, sampling_results, *args, **kwargs):
        calls.append((mask_preds.detach().clone(), sampling_results))
        return original(mask_preds, sampling_results, *args, **kwargs)

    data = model.data_preprocessor(paired_batch(), True)
    with mock.patch.object(head, 'loss_and_target', side_effect=spy):
        losses = model.loss(data['inputs'], data['data_samples'])
    assert len(calls) == 1  # the last stage's head only
    student_logits, sampling = calls[0]
    rois = bbox2roi([res.pos_priors for res in sampling])
    labels = torch.cat([res.pos_gt_labels for res in sampling])
    assert len(rois) > 0
    with torch.no_grad():
        teacher_logits = teacher_mask_logits(
            model.teacher, data['inputs'][:, 3:], rois)
    index = torch.arange(len(labels))
    expected = CBNetDistillLoss()(student_logits[index, labels],
                                  teacher_logits[index, labels])
    assert expected.item() > 1e-4
    torch.testing.assert_close(losses['loss_distill'].detach(), expected)
