"""CBNetRNGStateHook on a mock runner."""
import io
import random
from unittest.mock import MagicMock

import numpy as np
import pytest
import torch
import torch.nn as nn
from mmdet.registry import HOOKS

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.engine.hooks import CBNetRNGStateHook
from cbnet_mmdet.engine.hooks.rng_state_hook import (get_rng_state,
                                                     set_rng_state)


def mock_runner(it=16, epoch=1):
    runner = MagicMock()
    runner.iter, runner.epoch = it, epoch
    runner.model = nn.Linear(2, 2)
    return runner


def test_registered_name_builds_this_class():
    assert HOOKS.get('CBNetRNGStateHook') is CBNetRNGStateHook
    # scoped: found whatever default scope an earlier test left current
    hook = HOOKS.build(dict(type='mmdet.CBNetRNGStateHook'))
    assert type(hook) is CBNetRNGStateHook


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
