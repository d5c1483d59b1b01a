"""CBNetDehazeModel: supervised and unpaired objectives, predict."""
import pytest
import torch
from mmdet.registry import MODELS
from mmdet.structures import DetDataSample
from mmengine.optim import OptimWrapper

import cbnet_dehaze  # noqa: F401
from cbnet_dehaze.models.losses.ssim_loss import ssim

DEHAZER = dict(type='CBNetAttentionDehazer', channels=8, num_blocks=1)


def paired_batch(n=2, h=40, w=48, seed=0):
    """Uint8 BGR foggy (0-2) + clear (3-5) images, as the loader gives."""
    g = torch.Generator().manual_seed(seed)
    clear = torch.randint(0, 256, (n, 3, h, w), generator=g)
    foggy = (clear * 0.5 + 0.5 * 230).round()
    inputs = [torch.cat([f, c]).to(torch.uint8)
              for f, c in zip(foggy, clear)]
    samples = [DetDataSample(metainfo=dict(img_shape=(h, w)))
               for _ in range(n)]
    return dict(inputs=inputs, data_samples=samples)


def unpaired_model():
    torch.manual_seed(0)
    return MODELS.build(
        dict(type='CBNetDehazeModel', dehazer=DEHAZER, objective='unpaired',
             discriminator=dict(type='CBNetPatchDiscriminator', channels=8),
             loss_nce=dict(type='CBNetPatchNCELoss', num_patches=16)))


def test_supervised_losses_match_definitions():
    torch.manual_seed(0)
    model = MODELS.build(dict(type='CBNetDehazeModel', dehazer=DEHAZER))
    torch.nn.init.normal_(model.dehazer.tail.weight, std=0.05)
    data = model.data_preprocessor(paired_batch(), True)
    inputs = data['inputs']
    assert inputs.shape == (2, 6, 40, 48) and inputs.max() <= 1
    losses = model(**data, mode='loss')
    foggy_rgb = inputs[:, :3]
    pred = model.dehazer(foggy_rgb)
    clear = inputs[:, 3:]
    torch.testing.assert_close(losses['loss_l1'], (pred - clear).abs().mean())
    torch.testing.assert_close(losses['loss_ssim'],
                               (1 - ssim(pred, clear)).mean())
    # the preprocessor scaled to [0, 1] and swapped BGR to RGB
    raw = paired_batch()['inputs'][0].float() / 255
    torch.testing.assert_close(inputs[0, :3], raw[[2, 1, 0]])
    torch.testing.assert_close(inputs[0, 3:], raw[[5, 4, 3]])


def test_supervised_train_step_reduces_loss():
    torch.manual_seed(0)
    model = MODELS.build(dict(type='CBNetDehazeModel', dehazer=DEHAZER))
    optim = OptimWrapper(torch.optim.Adam(model.parameters(), lr=3e-3))
    data = paired_batch()
    first = model.train_step(data, optim)['loss'].item()
    for _ in range(15):
        last = model.train_step(data, optim)['loss'].item()
    assert last < 0.8 * first


def test_unpaired_step_trains_generator_and_discriminator():
    model = unpaired_model()
    torch.nn.init.normal_(model.dehazer.tail.weight, std=0.05)
    optim = OptimWrapper(torch.optim.Adam(model.parameters(), lr=1e-3))
    before = {k: v.clone() for k, v in model.state_dict().items()}
    log = model.train_step(paired_batch(), optim)
    assert {'loss_adv', 'loss_nce', 'loss_idt', 'loss_d', 'loss'} <= set(log)
    assert all(torch.isfinite(v) for v in log.values())
    after = model.state_dict()
    for part in ('dehazer.', 'discriminator.', 'loss_nce.'):
        assert any(not torch.equal(before[k], after[k])
                   for k in before if k.startswith(part)), part
    with pytest.raises(ValueError, match='>= 2'):
        model.train_step(paired_batch(n=1), optim)
    with pytest.raises(ValueError, match='features'):
        MODELS.build(dict(type='CBNetDehazeModel', objective='unpaired',
                          dehazer=dict(type='CBNetDarkChannelPrior')))


def test_unpaired_discriminator_gradient_is_its_own_loss():
    """The generator's adversarial term must not leak into D's step."""
    model = unpaired_model()
    seen = {}

    class Spy(OptimWrapper):

        def step(self, **kwargs):
            seen.update({n: p.grad.clone() for n, p in
                         model.discriminator.named_parameters()})

    model.train_step(paired_batch(), Spy(torch.optim.SGD(
        model.parameters(), lr=0.0)))
    data = model.data_preprocessor(paired_batch(), True)
    foggy, clear = model.split(data['inputs'])
    torch.manual_seed(0)
    model.zero_grad()
    _, d_loss = model.unpaired_losses(foggy, clear)
    d_loss.backward()
    for n, p in model.discriminator.named_parameters():
        torch.testing.assert_close(seen[n], p.grad, atol=1e-6, rtol=1e-4)


def test_predict_crops_to_image_shape():
    model = MODELS.build(dict(type='CBNetDehazeModel', dehazer=DEHAZER))
    data = paired_batch()
    data['data_samples'][1].set_metainfo(dict(img_shape=(30, 41)))
    out = model.test_step(data)
    assert out[0].pred_img.shape == (3, 40, 48)
    assert out[1].pred_img.shape == out[1].gt_img.shape == (3, 30, 41)
    # untrained dehazer = identity: the prediction is the hazy input
    torch.testing.assert_close(out[1].pred_img, out[1].hazy_img)
    assert not torch.allclose(out[1].hazy_img, out[1].gt_img)
    with pytest.raises(ValueError, match='paired'):
        model(torch.rand(1, 3, 8, 8), mode='loss')


def test_optional_perceptual_term_on_a_frozen_backbone():
    torch.manual_seed(0)
    model = MODELS.build(
        dict(type='CBNetDehazeModel', dehazer=DEHAZER,
             perceptual=dict(
                 backbone=dict(type='ResNet', depth=18, num_stages=2,
                               strides=(1, 2), dilations=(1, 1),
                               out_indices=(0, 1), base_channels=8,
                               init_cfg=None),
                 loss_weight=0.5)))
    torch.nn.init.normal_(model.dehazer.tail.weight, std=0.05)
    model.train()
    assert not model.perceptual.training
    data = model.data_preprocessor(paired_batch(), True)
    losses = model(**data, mode='loss')
    pred = model.dehazer(data['inputs'][:, :3])
    mean = torch.tensor([0.485, 0.456, 0.406]).view(1, 3, 1, 1)
    std = torch.tensor([0.229, 0.224, 0.225]).view(1, 3, 1, 1)
    fp = model.perceptual((pred - mean) / std)
    ft = model.perceptual((data['inputs'][:, 3:] - mean) / std)
    expected = 0.5 * sum((a - b).abs().mean() for a, b in zip(fp, ft)) / 2
    torch.testing.assert_close(losses['loss_perceptual'], expected)
    sum(losses.values()).backward()
    assert all(p.grad is None for p in model.perceptual.parameters())
    assert model.dehazer.tail.weight.grad is not None
