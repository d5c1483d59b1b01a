"""CBNetNormEvalHook: on a mock runner (the loop's ``train()`` then the
hook), and through MMEngine's own training loop, where a model whose batch
norms are the identity (folded weights) must keep them so."""
from unittest.mock import MagicMock

import pytest
import torch
import torch.nn as nn
from mmdet.registry import HOOKS
from mmengine.model import BaseModel
from mmengine.runner import Runner

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.engine.hooks import CBNetNormEvalHook


class Net(BaseModel):
    """conv -> BN in a 'backbone', conv -> BN in a 'head'; loss: the sum
    of the output."""

    def __init__(self):
        super().__init__()
        self.backbone = nn.Sequential(nn.Conv2d(3, 4, 3, padding=1),
                                      nn.BatchNorm2d(4))
        self.head = nn.Sequential(nn.Conv2d(4, 2, 1), nn.BatchNorm2d(2))
        # the identity-plus-bias batch norm of a folded checkpoint
        for bn in (self.backbone[1], self.head[1]):
            bn.running_mean.zero_()
            bn.running_var.fill_(1 - bn.eps)

    def forward(self, inputs, data_samples=None, mode='tensor'):
        out = self.head(self.backbone(inputs))
        if mode == 'loss':
            return dict(loss=(out ** 2).mean())
        return out


def runner_with(model):
    runner = MagicMock()
    runner.model = model
    return runner


def test_registered_and_checked():
    assert HOOKS.get('CBNetNormEvalHook') is CBNetNormEvalHook
    hook = HOOKS.build(dict(type='mmdet.CBNetNormEvalHook',
                            modules=['backbone']))
    assert hook.modules == ('backbone', )
    for bad in ('backbone', [1]):
        with pytest.raises(TypeError, match='list of submodule names'):
            CBNetNormEvalHook(modules=bad)


def test_norms_stay_in_eval_after_the_loops_train_call():
    model, hook = Net(), CBNetNormEvalHook()
    runner = runner_with(model)
    hook.before_train(runner)
    model.train()  # what the loop does before every iteration
    hook.before_train_iter(runner, 0)
    assert not model.backbone[1].training and not model.head[1].training
    assert model.backbone[0].training  # only the norms
    mean = model.head[1].running_mean.clone()
    model(torch.randn(2, 3, 8, 8) * 5 + 3)
    torch.testing.assert_close(model.head[1].running_mean, mean)
    # without the hook, the same forward moves the statistics
    model.train()
    model(torch.randn(2, 3, 8, 8) * 5 + 3)
    assert not torch.allclose(model.head[1].running_mean, mean)


def test_only_the_named_parts():
    model, hook = Net(), CBNetNormEvalHook(modules=['head'])
    runner = runner_with(model)
    model.train()
    hook.before_train_iter(runner, 0)
    assert model.backbone[1].training and not model.head[1].training
    with pytest.raises(KeyError, match=r"no submodule \['neck'\]"):
        CBNetNormEvalHook(modules=['neck']).before_train(runner)


def test_a_model_without_norms_is_said(caplog):
    model = nn.Sequential(nn.Linear(2, 2))
    hook = CBNetNormEvalHook()
    from mmengine.logging import MMLogger
    logger = MMLogger.get_instance('norm_eval_test')
    with pytest.MonkeyPatch.context() as mp:
        warned = []
        mp.setattr(logger, 'warning', warned.append)
        mp.setattr(MMLogger, 'get_current_instance',
                   classmethod(lambda cls: logger))
        hook.before_train(runner_with(model))
    assert warned and 'has no batch norm' in warned[0]


def test_mmengines_loop_keeps_folded_norms_and_trains_their_affine(tmp_path):
    """Four iterations of MMEngine's IterBasedTrainLoop: the running
    statistics stay the identity, the batch norms' weight and bias
    (and the convolutions) are trained."""
    model = Net()
    before = {k: v.clone() for k, v in model.state_dict().items()}
    data = [dict(inputs=torch.randn(3, 8, 8) * 4 + 2) for _ in range(8)]
    runner = Runner(
        model=model, work_dir=str(tmp_path),
        train_dataloader=dict(
            dataset=data, batch_size=2, num_workers=0,
            sampler=dict(type='DefaultSampler', shuffle=False),
            collate_fn=dict(type='default_collate')),
        train_cfg=dict(by_epoch=False, max_iters=4),
        optim_wrapper=dict(optimizer=dict(type='SGD', lr=0.1)),
        custom_hooks=[dict(type='mmdet.CBNetNormEvalHook')],
        default_hooks=dict(checkpoint=None, logger=None),
        default_scope='mmdet', log_level='WARNING')
    runner.train()
    after = model.state_dict()
    for bn in ('backbone.1', 'head.1'):
        torch.testing.assert_close(after[f'{bn}.running_mean'],
                                   before[f'{bn}.running_mean'])
        torch.testing.assert_close(after[f'{bn}.running_var'],
                                   before[f'{bn}.running_var'])
        assert not torch.equal(after[f'{bn}.weight'], before[f'{bn}.weight'])
    assert not torch.equal(after['backbone.0.weight'],
                           before['backbone.0.weight'])
