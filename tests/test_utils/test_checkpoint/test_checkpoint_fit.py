"""A checkpoint of another model is refused where the project loads it
(the whole model: every tensor must fit) and, through MMDetection's own
API too, by the CBNet components it offers tensors that do not fit them
(tests/test_models/test_utils/test_state_dict_fit.py); another number of
classes in the RoI heads still loads for fine-tuning, and a CBNet-DD
checkpoint, which offers them none of their names, is refused by the
project's loaders only.

The demo model (MiT-B0) stands in for every CBNet config; "another size"
is the same config with MiT-B1 (the B0-in-B5 case, smaller);
a CBNet-DD checkpoint is the demo model's weights under ``student.`` and
``teacher.``, as ``CBNetDistiller`` writes them.
"""
import os.path as osp

import pytest
import torch
from mmdet.apis import DetInferencer, init_detector
from mmdet.registry import MODELS
from mmengine.config import Config
from mmengine.registry import init_default_scope
from tool_helpers import load_tool

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.utils.checkpoint.files import read_checkpoint
from cbnet_mmdet.utils.checkpoint.fit import (CheckpointMismatchError,
                                              check_checkpoint_fits,
                                              compare_state_dicts,
                                              init_checked_detector,
                                              require_checkpoint_fit)

ROOT = osp.dirname(
    osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__)))))
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')


def _model(cfg):
    init_default_scope('mmdet')
    torch.manual_seed(0)
    model = MODELS.build(cfg.model)
    model.init_weights()
    return model


@pytest.fixture(scope='module')
def ckpts(tmp_path_factory):
    """Checkpoints: the demo model (B0), the B1 variant, a CBNet-DD one."""
    tmp = tmp_path_factory.mktemp('fit')
    cfg = Config.fromfile(DEMO)
    b1 = Config.fromfile(DEMO)
    b1.model.backbone.arch = 'b1'
    state = _model(cfg).state_dict()
    paths = dict(cfg=cfg, b1_cfg=b1)
    for name, sd in (('b0', state), ('b1', _model(b1).state_dict()),
                     ('dd', {f'{who}.{k}': v for who in ('student',
                                                         'teacher')
                             for k, v in state.items()})):
        paths[name] = str(tmp / f'{name}.pth')
        torch.save(dict(state_dict=sd, meta=dict()), paths[name])
    return paths


def test_the_matching_checkpoint_loads(ckpts):
    model = init_detector(ckpts['cfg'], ckpts['b0'], device='cpu')
    saved = torch.load(ckpts['b0'])['state_dict']
    for key, value in model.state_dict().items():
        torch.testing.assert_close(value, saved[key])


def test_other_backbone_size_refused_by_the_projects_loader(ckpts):
    # the B0 checkpoint in the B1 config (as B0 in the B5 config would be)
    with pytest.raises(CheckpointMismatchError) as err:
        init_checked_detector(ckpts['b1_cfg'], ckpts['b0'], device='cpu')
    message = str(err.value)
    assert message.startswith(f'the checkpoint {ckpts["b0"]} does not fit '
                              f'CascadeRCNN: ')
    assert 'mismatched' in message and \
        'backbone.layers.0.0.projection.weight: checkpoint (32,' in message
    assert 'use the config the checkpoint was trained with' in message


def test_mmdet_init_detector_refuses_another_backbone_size(ckpts):
    """MMDetection's own API: MMEngine's non-strict loading would skip the
    backbone tensors that do not fit; CBNetMiT refuses them itself."""
    with pytest.raises(CheckpointMismatchError) as err:
        init_detector(ckpts['b1_cfg'], ckpts['b0'], device='cpu')
    message = str(err.value)
    assert message.startswith('the checkpoint does not fit CBNetMiT at '
                              '`backbone`: ')
    assert 'layers.0.0.projection.weight: checkpoint (32,' in message
    with pytest.raises(CheckpointMismatchError, match='CBNetMiT'):
        DetInferencer(model=ckpts['b1_cfg'], weights=ckpts['b0'],
                      device='cpu', show_progress=False)


def test_distiller_checkpoint_refused_with_extract_hint(ckpts):
    with pytest.raises(CheckpointMismatchError,
                       match='extract_student.py'):
        init_checked_detector(ckpts['cfg'], ckpts['dd'], device='cpu')
    # MMDetection's inferencer loads nothing of it, with MMEngine's warning:
    # the components are offered none of their own names, which they
    # cannot tell from a partial checkpoint
    inferencer = DetInferencer(model=ckpts['cfg'], weights=ckpts['dd'],
                               device='cpu', show_progress=False)
    key = 'backbone.layers.0.0.projection.weight'
    saved = read_checkpoint(ckpts['dd'])['state_dict']['student.' + key]
    assert not torch.equal(inferencer.model.state_dict()[key].cpu(), saved)


def test_partial_fit_in_the_heads_still_loads_for_fine_tuning(
        ckpts, tmp_path):
    """Another number of classes (RoI heads only): MMEngine's warning, no
    error, so ``load_from`` fine-tuning keeps working."""
    state = torch.load(ckpts['b0'])['state_dict']
    bias = 'roi_head.bbox_head.0.fc_cls.bias'
    state[bias] = torch.zeros(3)
    path = str(tmp_path / 'classes.pth')
    torch.save(dict(state_dict=state), path)
    model = init_detector(ckpts['cfg'], path, device='cpu')
    assert model.state_dict()[bias].shape != (3, )


def test_whole_model_check_lists_what_does_not_fit():
    model = {'a': torch.zeros(2), 'b': torch.zeros(3),
             'bn.num_batches_tracked': torch.tensor(0)}
    ckpt = {'a': torch.zeros(2), 'b': torch.zeros(4), 'c': torch.zeros(1)}
    report = compare_state_dicts(model, ckpt)
    assert report == dict(loaded=['a'], missing=[], unexpected=['c'],
                          mismatched=['b: checkpoint (4,) vs model (3,)'])
    with pytest.raises(CheckpointMismatchError,
                       match=r'(?s)x.pth does not fit M: 1 of the 2 '
                       r'tensors it needs fit.*mismatched \(1\): b: '
                       r'checkpoint'):
        check_checkpoint_fits(model, ckpt, 'x.pth', 'M')
    # extra tensors alone are fine; a missing one is not
    assert check_checkpoint_fits(model, dict(ckpt, b=torch.zeros(3)))
    with pytest.raises(CheckpointMismatchError, match=r'missing \(1\): b'):
        check_checkpoint_fits(model, {'a': torch.zeros(2)})
    # a distiller's keys: the extract hint
    with pytest.raises(CheckpointMismatchError, match='extract_student'):
        check_checkpoint_fits(model, {'student.a': torch.zeros(2)})


def test_tools_test_refuses_a_partial_fit(ckpts, tmp_path, restore_environ):
    """tools/test.py: the report hook with require_fit refuses what
    MMEngine would load partly (here: one RoI-head tensor missing)."""
    from mmengine.registry import RUNNERS
    test_tool = load_tool('test.py')
    state = torch.load(ckpts['b0'])['state_dict']
    state.pop('roi_head.mask_head.conv_logits.weight')
    path = str(tmp_path / 'partial.pth')
    torch.save(dict(state_dict=state), path)
    cfg = test_tool.build_cfg(test_tool.parse_args(
        [DEMO, path, '--work-dir', str(tmp_path / 'work')]))
    hooks = [h for h in cfg.default_hooks.values()
             if h and h.get('type') == 'CBNetCheckpointReportHook']
    assert [h.get('require_fit') for h in hooks] == [True]
    cfg.experiment_name = f'fit_{tmp_path.name}'
    runner = RUNNERS.build(cfg)  # tools/test.py's CBNetRunner
    assert type(runner).__name__ == 'CBNetRunner'
    with pytest.raises(CheckpointMismatchError,
                       match=r'missing \(1\): roi_head.mask_head.conv_logits'):
        runner.load_or_resume()


def test_require_checkpoint_fit_adds_the_hook_where_missing():
    cfg = Config(dict(default_hooks=dict(timer=dict(type='IterTimerHook'))))
    require_checkpoint_fit(cfg)
    assert cfg.default_hooks.checkpoint_report == dict(
        type='CBNetCheckpointReportHook', require_fit=True)
