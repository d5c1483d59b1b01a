"""CBNetNonFiniteLossHook and CBNetRNGStateHook on a mock runner and in a
real (toy) training loop."""
import io
import math
import random
import re
from unittest.mock import MagicMock

import numpy as np
import pytest
import torch
import torch.nn as nn
from mmdet.registry import HOOKS
from mmdet.structures import DetDataSample
from mmengine.runner import Runner

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.engine.hooks import (CBNetNonFiniteLossHook,
                                      CBNetRNGStateHook)
from cbnet_mmdet.engine.hooks.rng_state_hook import (get_rng_state,
                                                     set_rng_state)


def mock_runner(it=16, epoch=1):
    runner = MagicMock()
    runner.iter, runner.epoch = it, epoch
    runner.model = nn.Linear(2, 2)
    return runner


def batch(*paths):
    return dict(data_samples=[
        DetDataSample(metainfo=dict(img_path=p)) for p in paths
    ])


def test_registered_names_build_these_classes():
    for name, cls in (('CBNetNonFiniteLossHook', CBNetNonFiniteLossHook),
                      ('CBNetRNGStateHook', CBNetRNGStateHook)):
        assert HOOKS.get(name) is cls
        # scoped: found whatever default scope an earlier test left current
        assert type(HOOKS.build(dict(type=f'mmdet.{name}'))) is cls


@pytest.mark.parametrize('bad', [math.nan, math.inf, -math.inf])
def test_non_finite_loss_names_iteration_loss_and_images(bad):
    hook = CBNetNonFiniteLossHook()
    outputs = dict(loss=torch.tensor(bad), s2_loss_mask=torch.tensor(bad),
                   s0_loss_cls=torch.tensor(0.3), acc=torch.tensor(50.))
    with pytest.raises(FloatingPointError) as err:
        hook.after_train_iter(mock_runner(), 3, batch('a.png', 'b.png'),
                              outputs)
    msg = str(err.value)
    assert 'iteration 17 (epoch 2, batch 3)' in msg
    assert f's2_loss_mask={bad}' in msg and f'loss={bad}' in msg
    assert 's0_loss_cls' not in msg
    assert 'a.png, b.png' in msg


def test_finite_losses_and_parameters_pass():
    hook = CBNetNonFiniteLossHook(param_interval=1)
    hook.after_train_iter(mock_runner(), 0, batch('a.png'),
                          dict(loss=torch.tensor(1.), n=torch.tensor(3),
                               empty=torch.zeros(0), f=2.5))


def test_non_finite_parameter_found_on_its_interval():
    runner = mock_runner(it=9)
    with torch.no_grad():
        runner.model.bias[1] = math.nan
    ok = dict(loss=torch.tensor(1.))
    CBNetNonFiniteLossHook(param_interval=3).after_train_iter(
        runner, 0, None, ok)  # iteration 10: not checked
    with pytest.raises(FloatingPointError, match=r'non-finite parameters '
                       r'after iteration 10 .*: bias \(1 tensors\)'):
        CBNetNonFiniteLossHook(param_interval=5).after_train_iter(
            runner, 0, None, ok)
    # huge but finite weights overflow the norm, which is no error
    runner.model = nn.Linear(2, 2)
    with torch.no_grad():
        runner.model.weight.fill_(3e38)
    assert not CBNetNonFiniteLossHook.non_finite_parameters(runner.model)


def test_non_finite_hook_rejects_bad_interval():
    with pytest.raises(ValueError, match='param_interval'):
        CBNetNonFiniteLossHook(param_interval=-1)


def test_training_stops_at_nan_without_saving_it(tmp_path):
    runner = toy_runner(tmp_path, dict(type='CBNetNonFiniteLossHook'),
                        max_iters=4, it3='nan')
    with pytest.raises(FloatingPointError,
                       match=r'iteration 3 .*loss_toy=nan'):
        runner.train()
    saved = sorted(p.name for p in tmp_path.glob('iter_*.pth'))
    assert saved == ['iter_1.pth', 'iter_2.pth']


def test_rng_state_round_trip_and_weights_only_load():
    random.seed(1), np.random.seed(1), torch.manual_seed(1)
    state = get_rng_state()
    expected = (random.random(), np.random.rand(), torch.rand(1))
    buf = io.BytesIO()
    torch.save(dict(rng_state=[state]), buf)
    buf.seek(0)
    loaded = torch.load(buf)  # weights_only=True by default
    random.seed(2), np.random.seed(2), torch.manual_seed(2)
    set_rng_state(loaded['rng_state'][0])
    assert (random.random(), np.random.rand()) == expected[:2]
    assert torch.equal(torch.rand(1), expected[2])


def test_rng_hook_restores_only_on_resume():
    hook = CBNetRNGStateHook()
    checkpoint = {}
    torch.manual_seed(5)
    hook.before_save_checkpoint(mock_runner(), checkpoint)
    after_save = torch.rand(3)
    # load_from (iteration 0): nothing restored
    hook.after_load_checkpoint(mock_runner(), checkpoint)
    torch.manual_seed(6)
    hook.before_train(mock_runner(it=0))
    assert not torch.equal(torch.rand(3), after_save)
    # resume: the generators continue where the checkpoint left them
    hook.after_load_checkpoint(mock_runner(), checkpoint)
    torch.manual_seed(6)
    runner = mock_runner(it=8)
    hook.before_train(runner)
    assert torch.equal(torch.rand(3), after_save)
    runner.logger.info.assert_called_once()


@pytest.mark.parametrize('saved', [None, 'two_ranks'])
def test_rng_hook_warns_when_it_cannot_restore(saved):
    hook = CBNetRNGStateHook()
    ckpt = {} if saved is None else dict(
        rng_state=[get_rng_state(), get_rng_state()])
    hook.after_load_checkpoint(mock_runner(), ckpt)
    runner = mock_runner(it=4)
    hook.before_train(runner)
    warning = runner.logger.warning.call_args[0][0]
    assert ('no RNG state' if saved is None else '2 rank(s)') in warning


def toy_runner(work_dir, hook, max_iters=6, **loss_scale):
    """MMEngine Runner of helper_hooks.CBNetTestToyModel with a checkpoint
    every iteration; ``loss_scale``: ``it3=1e4`` multiplies the 3rd loss."""
    from helper_hooks import CBNetTestToyModel
    scale = {k[2:]: v for k, v in loss_scale.items()}
    return Runner(
        model=CBNetTestToyModel(loss_scale=scale),
        work_dir=str(work_dir),
        train_dataloader=dict(
            dataset=[dict(inputs=torch.ones(2))] * 8,
            sampler=dict(type='DefaultSampler', shuffle=False),
            collate_fn=dict(type='pseudo_collate'),
            batch_size=1),
        optim_wrapper=dict(optimizer=dict(type='SGD', lr=0.01)),
        train_cfg=dict(by_epoch=False, max_iters=max_iters),
        default_hooks=dict(checkpoint=dict(
            type='CheckpointHook', interval=1, by_epoch=False)),
        custom_hooks=[hook],
        default_scope='mmdet')


def test_finite_blowup_stops_before_its_checkpoint(tmp_path):
    runner = toy_runner(
        tmp_path, dict(type='CBNetNonFiniteLossHook', min_history=2),
        it3=1e4)
    with pytest.raises(FloatingPointError) as err:
        runner.train()
    msg = str(err.value)
    assert type(err.value).__name__ == 'DivergenceError'
    assert re.match(r'loss blew up at iteration 3 \(epoch 1, batch 2\): '
                    r'\S+ is more than 100 x the median \S+ of the last 2 '
                    r'iterations', msg), msg
    assert (f'. The weights of this step were not saved; the last clean '
            f'checkpoint is {tmp_path}/iter_1.pth (iteration 1): resume '
            f'with --resume {tmp_path}/iter_1.pth; do NOT resume from '
            f'{tmp_path}/iter_2.pth (written after the weights went bad; a '
            f'plain --resume would). Lower the lr or check the data.') in msg
    saved = sorted(p.name for p in tmp_path.glob('iter_*.pth'))
    assert saved == ['iter_1.pth', 'iter_2.pth']


def test_nan_after_a_blowup_names_the_really_clean_checkpoint(tmp_path):
    """Blow-up at iteration 3 (before the finite check starts), NaN at 5:
    iter_3/iter_4.pth were written in between and are not clean."""
    runner = toy_runner(
        tmp_path, dict(type='CBNetNonFiniteLossHook', min_history=5),
        it3=1e4, it4=1e6, it5='nan')
    with pytest.raises(FloatingPointError) as err:
        runner.train()
    msg = str(err.value)
    assert msg.startswith('non-finite loss at iteration 5')
    assert (f'the blow-up began at iteration 3; the last clean checkpoint '
            f'is {tmp_path}/iter_1.pth (iteration 1)') in msg
    assert (f'do NOT resume from {tmp_path}/iter_4.pth, '
            f'{tmp_path}/iter_3.pth, {tmp_path}/iter_2.pth (written after '
            f'the weights went bad; a plain --resume would)') in msg


def test_grad_norm_blowup_against_running_median():
    from mmengine.logging import MessageHub
    hook = CBNetNonFiniteLossHook(min_history=3, window=4)
    runner = mock_runner()
    runner.message_hub = MessageHub(f'grad_norm_{id(hook)}')
    for it, norm in enumerate([3.0, 5.0, 4.0, 2.0, 6.0]):
        runner.iter = it
        runner.message_hub.update_scalar('train/grad_norm', norm)
        hook.after_train_iter(runner, it, None, dict(loss=torch.tensor(1.)))
    runner.iter = 5  # the last 4: 5, 4, 2, 6 -> median 4.5
    runner.message_hub.update_scalar('train/grad_norm', 449.0)
    hook.after_train_iter(runner, 5, None, dict(loss=torch.tensor(1.)))
    runner.iter = 6  # AMP's skipped step: an infinite norm, ignored
    runner.message_hub.update_scalar('train/grad_norm', math.inf)
    hook.after_train_iter(runner, 6, None, dict(loss=torch.tensor(1.)))
    runner.iter = 7  # now 4, 2, 6, 449 -> median 5
    runner.message_hub.update_scalar('train/grad_norm', 501.0)
    with pytest.raises(FloatingPointError,
                       match=r'grad_norm blew up at iteration 8 .*: 501 is '
                       r'more than 100 x the median 5 of the last 4 '):
        hook.after_train_iter(runner, 7, None, dict(loss=torch.tensor(1.)))


def test_parameter_norm_blowup():
    hook = CBNetNonFiniteLossHook(param_interval=1)
    runner = mock_runner(it=0)
    ok = dict(loss=torch.tensor(1.))
    hook.before_train(runner)  # the reference norm
    hook.after_train_iter(runner, 0, None, ok)
    with torch.no_grad():
        runner.model.weight.mul_(1e4)
        runner.model.bias.mul_(1e4)
    runner.iter = 1
    with pytest.raises(FloatingPointError,
                       match='parameter norm blew up after iteration 2'):
        hook.after_train_iter(runner, 1, None, ok)


@pytest.mark.parametrize('kwargs', [
    dict(blowup_factor=1), dict(blowup_factor=-5), dict(window=0),
    dict(min_history=1.5)
])
def test_divergence_settings_checked(kwargs):
    with pytest.raises(ValueError, match=list(kwargs)[0]):
        CBNetNonFiniteLossHook(**kwargs)
