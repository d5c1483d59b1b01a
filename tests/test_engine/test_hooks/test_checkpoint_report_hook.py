"""CBNetCheckpointReportHook on a mock runner: what it logs, what it
refuses."""
from unittest.mock import MagicMock

import pytest
import torch
import torch.nn as nn
from mmdet.registry import HOOKS

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.engine.hooks import CBNetCheckpointReportHook
from cbnet_mmdet.utils.checkpoint.fit import CheckpointMismatchError


def mock_runner():
    runner = MagicMock()
    runner.model = nn.Sequential(nn.Linear(2, 3), nn.Linear(3, 1))
    runner._load_from = 'work/ckpt.pth'
    return runner


def state(runner, **replace):
    weights = {k: v.clone() for k, v in runner.model.state_dict().items()}
    for key, value in replace.items():
        key = key.replace('_', '.')
        if value is None:
            del weights[key]
        else:
            weights[key] = value
    return weights


def test_registered():
    assert HOOKS.get('CBNetCheckpointReportHook') is \
        CBNetCheckpointReportHook


def test_a_fitting_checkpoint_is_one_info_line():
    runner = mock_runner()
    CBNetCheckpointReportHook().after_load_checkpoint(
        runner, dict(state_dict=state(runner)))
    runner.logger.info.assert_called_once_with(
        'CBNetCheckpointReportHook: 4 of 4 model tensors loaded from '
        'work/ckpt.pth')
    runner.logger.warning.assert_not_called()


def test_partial_fit_is_listed_by_kind():
    runner = mock_runner()
    ckpt = state(runner, **{'0_weight': torch.zeros(5, 2), '1_bias': None})
    ckpt['head.extra'] = torch.zeros(1)
    CBNetCheckpointReportHook().after_load_checkpoint(runner, ckpt)
    runner.logger.info.assert_called_once_with(
        'CBNetCheckpointReportHook: 2 of 4 model tensors loaded from '
        'work/ckpt.pth')
    assert runner.logger.warning.call_args[0][0] == (
        'CBNetCheckpointReportHook: not loaded from work/ckpt.pth:\n'
        '  missing (1): 1.bias\n'
        '  unexpected (1): head.extra\n'
        '  mismatched (1): 0.weight: checkpoint (5, 2) vs model (3, 2)')


def test_nothing_fits_is_refused_unless_allowed():
    runner = mock_runner()
    foreign = dict(state_dict={'backbone.w': torch.zeros(1)})
    with pytest.raises(ValueError, match=r'no tensor of work/ckpt.pth fits '
                       r'the model \(Sequential\)'):
        CBNetCheckpointReportHook().after_load_checkpoint(runner, foreign)
    CBNetCheckpointReportHook(allow_no_match=True).after_load_checkpoint(
        runner, foreign)
    assert 'missing (4)' in runner.logger.warning.call_args[0][0]


def test_require_fit_refuses_a_partial_fit():
    runner = mock_runner()
    ckpt = dict(state_dict=state(runner, **{'1_bias': None}))
    CBNetCheckpointReportHook().after_load_checkpoint(runner, ckpt)  # ok
    with pytest.raises(CheckpointMismatchError,
                       match=r'(?s)the checkpoint work/ckpt.pth does not '
                       r'fit Sequential: 3 of the 4 tensors it needs fit'
                       r'.*missing \(1\): 1.bias'):
        CBNetCheckpointReportHook(require_fit=True).after_load_checkpoint(
            runner, ckpt)
