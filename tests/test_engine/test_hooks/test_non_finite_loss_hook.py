"""CBNetNonFiniteLossHook on a mock runner and in a real (toy) training
loop; its state across a resume (the runner's side: test_cbnet_runner.py)."""
import hashlib
import json
import logging
import math
import re
from unittest.mock import MagicMock

import pytest
import torch
import torch.nn as nn
from mmdet.registry import HOOKS
from mmdet.structures import DetDataSample

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.engine.hooks import CBNetNonFiniteLossHook
from helper_hooks import toy_runner


def mock_runner(it=16, epoch=1):
    runner = MagicMock()
    runner.iter, runner.epoch = it, epoch
    runner.model = nn.Linear(2, 2)
    return runner


def batch(*paths):
    return dict(data_samples=[
        DetDataSample(metainfo=dict(img_path=p)) for p in paths
    ])


def test_registered_name_builds_this_class():
    assert HOOKS.get('CBNetNonFiniteLossHook') is CBNetNonFiniteLossHook
    # scoped: found whatever default scope an earlier test left current
    hook = HOOKS.build(dict(type='mmdet.CBNetNonFiniteLossHook'))
    assert type(hook) is CBNetNonFiniteLossHook


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
            f'with --resume {tmp_path}/iter_1.pth; {tmp_path}/iter_2.pth '
            f'were written after the weights went bad: --resume never '
            f'takes them (diverged.json in the work dir says so). Lower '
            f'the lr or check the data.') in msg
    saved = sorted(p.name for p in tmp_path.glob('iter_*.pth'))
    assert saved == ['iter_1.pth', 'iter_2.pth']
    record = json.loads((tmp_path / 'diverged.json').read_text())
    assert record['error'] == msg
    data = (tmp_path / 'iter_2.pth').read_bytes()
    assert record['unsafe'] == {'iter_2.pth': dict(
        size=len(data), sha256=hashlib.sha256(data).hexdigest())}


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
    assert (f'; {tmp_path}/iter_4.pth, {tmp_path}/iter_3.pth, '
            f'{tmp_path}/iter_2.pth were written after the weights went '
            f'bad: --resume never takes them') in msg
    record = json.loads((tmp_path / 'diverged.json').read_text())
    assert sorted(record['unsafe']) == ['iter_2.pth', 'iter_3.pth',
                                        'iter_4.pth']


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


def test_state_is_saved_and_restored_only_on_resume():
    """The histories, the reference norm and the counters go into every
    checkpoint and come back on resume, not after ``load_from``."""
    hook = CBNetNonFiniteLossHook(param_interval=1, window=3)
    runner = mock_runner(it=0)
    hook.before_train(runner)
    for it, loss in enumerate([4.0, 2.0, 3.0, 5.0]):
        runner.iter = it
        hook.after_train_iter(runner, it, None, dict(loss=torch.tensor(loss)))
    checkpoint = {}
    hook.before_save_checkpoint(runner, checkpoint)
    state = checkpoint['non_finite_check']
    # the window keeps the last 3 (iteration, loss) pairs, 1-based
    assert state['history'] == {'loss': [[2, 2.0], [3, 3.0], [4, 5.0]]}
    assert state['last_params_ok'] == 4
    norm = float(torch.cat([p.detach().flatten() for p in
                            runner.model.parameters()]).double().norm())
    assert state['first_param_norm'] == pytest.approx(norm, rel=1e-6)
    # load_from (iteration 0): a new history
    fresh = CBNetNonFiniteLossHook(param_interval=1, window=3)
    fresh.after_load_checkpoint(runner, checkpoint)
    fresh.before_train(mock_runner(it=0))
    assert fresh.history == {} and fresh.last_params_ok == 0
    # resume at iteration 4: the same state as the hook that saved it
    resumed = CBNetNonFiniteLossHook(param_interval=1, window=3)
    resumed.after_load_checkpoint(runner, checkpoint)
    runner.iter = 4
    resumed.before_train(runner)
    assert resumed.state_dict() == state
    assert resumed.history['loss'].maxlen == 3
    # judged against the losses before the interruption: median 3
    with pytest.raises(FloatingPointError,
                       match=r'loss blew up at iteration 5 .*: 301 is more '
                       r'than 100 x the median 3 of the last 3 iterations'):
        resumed.after_train_iter(runner, 0, None,
                                 dict(loss=torch.tensor(301.)))


def test_resume_from_a_checkpoint_without_state_warns():
    hook = CBNetNonFiniteLossHook()
    hook.after_load_checkpoint(mock_runner(), {})
    runner = mock_runner(it=8)
    hook.before_train(runner)
    assert 'holds no state of this check' in \
        runner.logger.warning.call_args[0][0]


def test_a_steep_rise_below_the_stop_is_a_warning(tmp_path, log_messages):
    """An lr far too high: the loss 50 x its median, not yet 100 x."""
    runner = toy_runner(
        tmp_path, dict(type='CBNetNonFiniteLossHook', min_history=2),
        max_iters=5, it3=50, it5=30)
    seen = log_messages(runner.logger, logging.WARNING)
    runner.train()  # not stopped
    rises = [w for w in seen if 'rose to' in w]
    assert len(rises) == 1, seen  # once per run
    assert re.search(r'loss rose to \S+ at iteration 3 \(epoch 1, batch 2\)'
                     r', \S+ x the median \S+ of the last 2 iterations; '
                     r'training stops at 100 x', rises[0]), rises[0]
    ratio = float(re.search(r', (\S+) x the median', rises[0])[1])
    assert 10 < ratio < 100


def test_warn_factor_off_and_checked(tmp_path, log_messages):
    runner = toy_runner(
        tmp_path, dict(type='CBNetNonFiniteLossHook', warn_factor=0),
        max_iters=4, it3=50)
    seen = log_messages(runner.logger, logging.WARNING)
    runner.train()
    assert not [w for w in seen if 'rose to' in w]
    for bad in (dict(warn_factor=1), dict(start_factor=-1),
                dict(start_factor='x')):
        with pytest.raises(ValueError, match=list(bad)[0]):
            CBNetNonFiniteLossHook(**bad)


def load_from_runner(tmp_path, weight, **hook):
    """tools/train.py's runner (CBNetRunner from a config) starting from a
    checkpoint of the toy model whose weights are all ``weight``."""
    from mmengine.config import Config
    from mmengine.registry import RUNNERS
    from helper_hooks import toy_config
    ckpt = tmp_path / 'start.pth'
    torch.save(dict(state_dict={'fc.weight': torch.full((1, 2), weight),
                                'fc.bias': torch.full((1, ), weight)},
                    meta={}), ckpt)
    cfg = Config.fromfile(toy_config(
        str(tmp_path / 'work'), max_iters=2,
        custom_hooks=[dict(type='CBNetNonFiniteLossHook', **hook)]))
    cfg.work_dir = str(tmp_path / 'work')
    cfg.load_from = str(ckpt)
    return RUNNERS.build(cfg), str(ckpt)


def test_unsound_load_from_weights_stop_at_the_first_iteration(tmp_path):
    """Weights written after a run diverged, with no record of it (another
    machine): the first loss is ~1e12 x a fresh model's."""
    runner, ckpt = load_from_runner(tmp_path, 1e6)
    with pytest.raises(FloatingPointError) as err:
        runner.train()
    assert type(err.value).__name__ == 'DivergenceError'
    assert re.match(r'the first loss \S+ is more than 100 x the loss \S+ of '
                    r'a freshly initialised model of this config on the same '
                    rf'batch: the weights of load_from {re.escape(ckpt)} are '
                    r'not sound', str(err.value)), str(err.value)
    assert not list((tmp_path / 'work').glob('iter_*.pth'))


def test_sound_load_from_weights_train_and_both_losses_are_logged(
        tmp_path, log_messages):
    runner, ckpt = load_from_runner(tmp_path, 0.4)  # loss 0.04, fresh ~1
    infos = log_messages(runner.logger)
    runner.train()
    start = [m for m in infos if 'a fresh model of this config' in m]
    assert len(start) == 1
    assert re.search(rf'first loss 0.04 from the weights of '
                     rf'{re.escape(ckpt)}; a fresh model of this config: '
                     r'\S+ on the same batch', start[0]), start[0]
    # off: no fresh model at all
    (tmp_path / 'off').mkdir()
    runner, _ = load_from_runner(tmp_path / 'off', 1e6, start_factor=0)
    runner.train()


def test_fresh_loss_leaves_the_random_state_alone(tmp_path):
    import random
    import numpy as np
    runner, _ = load_from_runner(tmp_path, 0.4)
    states = (random.getstate(), np.random.get_state()[1].copy(),
              torch.get_rng_state().clone())
    loss = CBNetNonFiniteLossHook.fresh_loss(
        runner, dict(inputs=[torch.ones(2)]))
    # the toy model: ((w . [1, 1] + b) - 1)^2 of a fresh nn.Linear(2, 1)
    assert loss >= 0 and math.isfinite(loss)
    assert random.getstate() == states[0]
    assert (np.random.get_state()[1] == states[1]).all()
    assert torch.equal(torch.get_rng_state(), states[2])
    with pytest.raises(ValueError, match='model object'):
        CBNetNonFiniteLossHook.fresh_loss(mock_runner(), None)
