"""The CBNet components refuse tensors that do not fit them, whoever loads
them (PyTorch's non-strict ``load_state_dict``, MMEngine's
``load_state_dict`` / ``load_checkpoint``), and load what is theirs.

The reference for "what does not fit" is computed here from the two state
dicts' shapes, independently of the package's comparison.
"""
import pytest
import torch
from mmdet.registry import MODELS
from mmdet.utils import register_all_modules
from mmengine.runner.checkpoint import load_checkpoint, load_state_dict
from torch import nn

import cbnet_mmdet  # noqa: F401  (registers the components)
from cbnet_mmdet.utils.checkpoint.fit import CheckpointMismatchError

register_all_modules()

TINY = dict(embed_dims=[8, 16, 24, 32], depths=[1, 2, 1, 1],
            num_heads=[1, 2, 3, 4], sr_ratios=[8, 4, 2, 1])
WIDER = dict(TINY, embed_dims=[8, 16, 24, 40])
DEEPER = dict(TINY, depths=[1, 2, 1, 2])


def mit(arch=TINY, seed=0, **kwargs):
    torch.manual_seed(seed)
    model = MODELS.build(
        dict(type='CBNetMiT', arch=arch, init_cfg=None, **kwargs))
    model.init_weights()
    return model


class Detector(nn.Module):
    """A model with the backbone where a detector keeps it."""

    def __init__(self, backbone):
        super().__init__()
        self.backbone = backbone
        self.neck = nn.Conv2d(2, 2, 1)


def shape_misfits(model_state, ckpt_state):
    return sorted(k for k in model_state if k in ckpt_state
                  and model_state[k].shape != ckpt_state[k].shape)


def test_same_architecture_loads_exactly():
    target, source = mit(seed=0), mit(seed=1)
    target.load_state_dict(source.state_dict())
    for key, value in source.state_dict().items():
        assert torch.equal(target.state_dict()[key], value), key


@pytest.mark.parametrize('loader', ['torch', 'mmengine'])
def test_another_width_refused_naming_the_tensors(loader):
    target, source = Detector(mit(TINY)), Detector(mit(WIDER))
    before = target.state_dict()['backbone.layers.3.2.weight'].clone()
    expected = shape_misfits(target.state_dict(), source.state_dict())
    assert expected  # the reference: some tensors have other shapes
    with pytest.raises(CheckpointMismatchError) as err:
        if loader == 'torch':
            target.load_state_dict(source.state_dict(), strict=False)
        else:
            load_state_dict(target, source.state_dict(), strict=False)
    message = str(err.value)
    assert message.startswith('the checkpoint does not fit CBNetMiT at '
                              '`backbone`')
    assert f'other shape ({len(expected)}):' in message
    # listed in the model's order (the first 10), with both shapes
    own, offered = target.backbone.state_dict(), source.backbone.state_dict()
    first = next(k for k in own if own[k].shape != offered[k].shape)
    assert (f'{first}: checkpoint {tuple(offered[first].shape)} vs model '
            f'{tuple(own[first].shape)}') in message
    assert 'use the config the checkpoint was trained with' in message
    # nothing of the backbone was half-loaded
    assert torch.equal(target.state_dict()['backbone.layers.3.2.weight'],
                       before)


def test_another_depth_refused_as_missing():
    target, source = mit(DEEPER), mit(TINY)
    with pytest.raises(CheckpointMismatchError,
                       match=r'missing \(\d+\): layers\.3\.1\.1\.'):
        target.load_state_dict(source.state_dict(), strict=False)


def test_another_trunk_refused():
    target = Detector(mit())
    state = {'backbone.stem.conv.weight': torch.zeros(4, 3, 3, 3),
             'neck.weight': torch.zeros(2, 2, 1, 1)}
    with pytest.raises(CheckpointMismatchError,
                       match=r'(?s)offers 1 tensors for it, 0 of the .*'
                       r'not CBNetMiT tensors \(1\): stem.conv.weight'):
        target.load_state_dict(state, strict=False)


def test_checkpoint_file_refused_by_mmengine_load_checkpoint(tmp_path):
    path = tmp_path / 'wider.pth'
    torch.save(dict(state_dict=Detector(mit(WIDER)).state_dict()), path)
    with pytest.raises(CheckpointMismatchError, match='CBNetMiT'):
        load_checkpoint(Detector(mit()), str(path), map_location='cpu')


def test_what_offers_the_backbone_nothing_loads_as_before():
    target = Detector(mit())
    before = {k: v.clone() for k, v in target.state_dict().items()}
    neck = {'neck.weight': torch.ones(2, 2, 1, 1), 'neck.bias': torch.ones(2)}
    result = target.load_state_dict(neck, strict=False)
    assert torch.equal(target.neck.weight, neck['neck.weight'])
    assert all(k.startswith('backbone.') for k in result.missing_keys)
    for key, value in target.backbone.state_dict().items():
        assert torch.equal(value, before['backbone.' + key])


def test_distiller_checkpoint_offers_the_backbone_nothing():
    """Both loaders offer a module only the keys under its prefix: a
    CBNet-DD checkpoint (``student.``, ``teacher.``) offers the backbone
    nothing, which it cannot tell from a partial checkpoint; it loads
    nothing, MMEngine lists every tensor as missing (the project's tools
    refuse it: tests/test_utils/test_checkpoint/test_checkpoint_fit.py)."""
    target = Detector(mit())
    before = {k: v.clone() for k, v in target.state_dict().items()}
    state = {f'{who}.{k}': v + 1 for who in ('student', 'teacher')
             for k, v in before.items()}
    load_state_dict(target, state, strict=False)
    result = target.load_state_dict(state, strict=False)
    assert len(result.unexpected_keys) == len(state)
    for key, value in target.state_dict().items():
        assert torch.equal(value, before[key]), key


def test_cspe_tables_may_be_missing_and_stay_zero():
    ope = mit(pos_encoding='ope', seed=1)
    cspe = mit(pos_encoding='cspe')
    result = cspe.load_state_dict(ope.state_dict(), strict=False)
    assert result.missing_keys and all(
        k.endswith('cspe.table') for k in result.missing_keys)
    for key, value in cspe.state_dict().items():
        if key.endswith('cspe.table'):
            assert value.abs().sum() == 0, key
        else:
            assert torch.equal(value, ope.state_dict()[key]), key
    # any other missing tensor is not optional
    state = ope.state_dict()
    state.pop('layers.0.2.weight')
    with pytest.raises(CheckpointMismatchError,
                       match=r'missing \(1\): layers.0.2.weight'):
        mit(pos_encoding='ope').load_state_dict(state, strict=False)


def nas_fpn(**kwargs):
    cfg = dict(type='CBNetNASFPN', in_channels=[8, 16, 24, 32],
               out_channels=8, stack_times=1, init_cfg=None)
    cfg.update(kwargs)
    return MODELS.build(cfg)


def test_nas_fpn_refuses_another_depth_and_width():
    target = nas_fpn()
    target.load_state_dict(nas_fpn().state_dict())  # same: loads
    with pytest.raises(CheckpointMismatchError, match='CBNetNASFPN'):
        nas_fpn(stack_times=2).load_state_dict(target.state_dict(),
                                               strict=False)
    wider = nas_fpn(out_channels=16).state_dict()
    expected = shape_misfits(target.state_dict(), wider)
    with pytest.raises(CheckpointMismatchError,
                       match=rf'other shape \({len(expected)}\)'):
        target.load_state_dict(wider, strict=False)


def rpn(**kwargs):
    cfg = dict(type='CBNetCascadeRPNHead', in_channels=8, feat_channels=8)
    cfg.update(kwargs)
    return MODELS.build(cfg)


def test_cascade_rpn_refuses_another_width():
    target = rpn()
    target.load_state_dict(rpn().state_dict())  # same: loads
    wider = rpn(feat_channels=16).state_dict()
    with pytest.raises(CheckpointMismatchError,
                       match='does not fit CBNetCascadeRPNHead'):
        target.load_state_dict(wider, strict=False)
