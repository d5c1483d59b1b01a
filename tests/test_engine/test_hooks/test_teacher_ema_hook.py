import copy
import logging
from unittest.mock import MagicMock

import pytest
import torch
import torch.nn as nn
from mmdet.registry import HOOKS
from mmengine.model import BaseModel

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.engine.runner import CBNetRunner


class Net(nn.Module):

    def __init__(self):
        super().__init__()
        self.fc = nn.Linear(4, 3)
        self.bn = nn.BatchNorm1d(3)


class ToyDistiller(BaseModel):
    """Student/teacher pair with a regression loss."""

    def __init__(self):
        super().__init__()
        self.student = Net()
        self.teacher = Net()
        self.teacher.requires_grad_(False)
        self.eval_with = 'student'

    def forward(self, inputs, data_samples=None, mode='tensor'):
        out = self.student.bn(self.student.fc(inputs))
        if mode == 'loss':
            return dict(loss=((out - data_samples)**2).mean())
        return out


class ToyDataset(torch.utils.data.Dataset):

    def __len__(self):
        return 8

    def __getitem__(self, i):
        g = torch.Generator().manual_seed(i)
        return dict(
            inputs=torch.randn(4, generator=g),
            data_samples=torch.randn(3, generator=g))


def build_hook(**kwargs):
    # scoped name: found whatever default scope an earlier test's Runner
    # left current (e.g. 'mmengine', whose hook registry lacks ours)
    return HOOKS.build(dict(type='mmdet.CBNetTeacherEMAHook', **kwargs))


def mock_runner(model, iteration=0):
    runner = MagicMock()
    runner.model = model
    runner.iter = iteration
    runner.logger = MagicMock(spec=logging.Logger)
    return runner


def randomise(module, seed):
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for t in list(module.parameters()) + list(module.buffers()):
            if t.is_floating_point():
                t.copy_(torch.randn(t.shape, generator=g))
            else:
                t.fill_(seed)


def test_ema_matches_formula():
    model = ToyDistiller()
    randomise(model.student, 1)
    randomise(model.teacher, 2)
    s0 = copy.deepcopy(model.student.state_dict())
    t0 = copy.deepcopy(model.teacher.state_dict())
    hook = build_hook(momentum=0.9)
    hook.after_train_iter(mock_runner(model), 0)
    for key, value in model.teacher.state_dict().items():
        if value.is_floating_point():  # params and BN running stats
            torch.testing.assert_close(value, 0.9 * t0[key] + 0.1 * s0[key])
        else:  # num_batches_tracked is copied
            assert torch.equal(value, s0[key])
    assert all(torch.equal(v, s0[k])
               for k, v in model.student.state_dict().items())


def test_skip_buffers_and_interval():
    model = ToyDistiller()
    randomise(model.student, 1)
    randomise(model.teacher, 2)
    t0 = copy.deepcopy(model.teacher.state_dict())
    hook = build_hook(momentum=0.5, interval=2, skip_buffers=True)
    hook.after_train_iter(mock_runner(model, iteration=0), 0)  # skipped
    assert all(torch.equal(v, t0[k])
               for k, v in model.teacher.state_dict().items())
    hook.after_train_iter(mock_runner(model, iteration=1), 1)
    assert not torch.equal(model.teacher.fc.weight, t0['fc.weight'])
    assert torch.equal(model.teacher.bn.running_mean, t0['bn.running_mean'])


def test_before_train_copies_student_only_on_fresh_run():
    model = ToyDistiller()
    randomise(model.student, 1)
    randomise(model.teacher, 2)
    t0 = copy.deepcopy(model.teacher.state_dict())
    build_hook().before_train(mock_runner(model, iteration=5))
    assert torch.equal(model.teacher.fc.weight, t0['fc.weight'])
    build_hook().before_train(mock_runner(model, iteration=0))
    for key, value in model.student.state_dict().items():
        assert torch.equal(model.teacher.state_dict()[key], value)


@pytest.mark.parametrize('prefix', ['', 'teacher.', 'module.teacher.'])
def test_teacher_checkpoint(tmp_path, prefix):
    source = Net()
    randomise(source, 7)
    state = {prefix + k: v for k, v in source.state_dict().items()}
    if prefix:  # a distiller checkpoint also holds the student
        state.update({
            prefix.replace('teacher', 'student') + k: torch.zeros_like(v)
            for k, v in source.state_dict().items()
        })
    state[prefix + 'extra.weight'] = torch.zeros(1)
    del state[prefix + 'bn.bias']
    path = str(tmp_path / 'teacher.pth')
    torch.save(dict(state_dict=state, meta=dict()), path)

    model = ToyDistiller()
    runner = mock_runner(model)
    build_hook(teacher_checkpoint=path).before_train(runner)
    assert torch.equal(model.teacher.fc.weight, source.fc.weight)
    assert not torch.equal(model.teacher.fc.weight, model.student.fc.weight)
    logged = ' '.join(str(c) for c in runner.logger.log.call_args_list)
    assert 'extra.weight' in logged and 'bn.bias' in logged
    with pytest.raises(RuntimeError, match='bn.bias'):
        build_hook(teacher_checkpoint=path, strict=True).before_train(runner)


def test_eval_with_is_the_models_and_bad_config():
    """The model chosen for validation and testing is the model's setting
    (CBNetDistiller's eval_with): the hook neither takes nor changes it."""
    model = ToyDistiller()
    model.eval_with = 'teacher'
    hook = build_hook()
    runner = mock_runner(model)
    hook.before_train(runner)
    hook.before_val(runner)
    hook.before_test(runner)
    assert model.eval_with == 'teacher'
    with pytest.raises(TypeError, match='eval_with'):
        build_hook(eval_with='teacher')
    for bad in (dict(momentum=1.0), dict(momentum=0), dict(interval=0)):
        with pytest.raises(ValueError):
            build_hook(**bad)
    with pytest.raises(TypeError, match='student'):
        build_hook().before_train(mock_runner(Net()))
    model.teacher.extra = nn.Linear(1, 1)
    with pytest.raises(RuntimeError, match='extra'):
        build_hook().after_train_iter(mock_runner(model), 0)


def run(work_dir, max_iters, resume=False, load_from=None):
    torch.manual_seed(0)  # the same initial model in every run
    # the project's runner: it reads MMEngine's checkpoints on this torch
    runner = CBNetRunner(
        model=ToyDistiller(),
        work_dir=str(work_dir),
        train_dataloader=dict(
            dataset=ToyDataset(),
            sampler=dict(type='DefaultSampler', shuffle=True),
            collate_fn=dict(type='default_collate'),
            batch_size=2,
            num_workers=0),
        optim_wrapper=dict(
            optimizer=dict(type='SGD', lr=0.1, momentum=0.9)),
        train_cfg=dict(by_epoch=False, max_iters=max_iters),
        custom_hooks=[
            dict(type='CBNetTeacherEMAHook', momentum=0.8, interval=2)
        ],
        default_hooks=dict(
            checkpoint=dict(
                type='CheckpointHook', interval=3, by_epoch=False),
            logger=dict(type='LoggerHook', interval=100)),
        randomness=dict(seed=0),
        resume=resume,
        load_from=load_from,
        default_scope='mmdet',
        experiment_name=f'ema_{max_iters}_{resume}')
    runner.train()
    return runner.model.teacher.state_dict()


def test_resume_reproduces_uninterrupted_teacher(tmp_path):
    straight = run(tmp_path / 'straight', 6)
    run(tmp_path / 'first', 3)
    resumed = run(
        tmp_path / 'resumed',
        6,
        resume=True,
        load_from=str(tmp_path / 'first' / 'iter_3.pth'))
    for key, value in straight.items():
        assert torch.equal(resumed[key], value), key
    assert not torch.equal(straight['fc.weight'],
                           run(tmp_path / 'short', 4)['fc.weight'])
