"""``CBNetMish`` / ``mish`` against PyTorch's own ``nn.Mish``."""
import pytest
import torch
import torch.nn.functional as F
from mmcv.cnn import build_activation_layer

import cbnet_mmdet.models.layers.cbnet_mish as cbnet_mish
from cbnet_mmdet.models.layers import CBNetMish, mish

# edges of the formula: the exp clamp (20), underflow, infinities
EDGES = [-1e4, -100., -88., -30., -20., -5., -1e-3, 0., 1e-3, 1., 5., 19.9,
         20., 20.1, 50., 1e4]


@pytest.mark.parametrize('dtype', [torch.float32, torch.float64])
def test_values_and_gradients_match_torch(dtype):
    x = torch.cat([torch.tensor(EDGES, dtype=dtype),
                   torch.randn(997, dtype=dtype) * 6])
    ours = x.clone().requires_grad_()
    ref = x.clone().requires_grad_()
    grad = torch.randn_like(x)
    mish(ours).backward(grad)
    F.mish(ref).backward(grad)
    tol = dict(rtol=1e-5, atol=1e-6) if dtype == torch.float32 else {}
    torch.testing.assert_close(mish(x), F.mish(x), **tol)
    torch.testing.assert_close(ours.grad, ref.grad, **tol)


def test_gradcheck():
    x = (torch.randn(64, dtype=torch.float64) * 8).requires_grad_()
    assert torch.autograd.gradcheck(mish, (x, ))


def test_infinities_and_nan_as_torch():
    x = torch.tensor([float('inf'), float('-inf'), float('nan')])
    torch.testing.assert_close(mish(x), F.mish(x), equal_nan=True)


@pytest.mark.parametrize('memory_format',
                         [torch.contiguous_format, torch.channels_last])
def test_blocks_and_layouts(monkeypatch, memory_format):
    """Several blocks (a small CHUNK), a last partial block, both layouts of
    a 4-D tensor, and a gradient in the other layout than the input."""
    monkeypatch.setattr(cbnet_mish, 'CHUNK', 100)
    x = torch.randn(2, 7, 5, 9).to(memory_format=memory_format)
    out = mish(x)
    assert out.is_contiguous(memory_format=memory_format)
    torch.testing.assert_close(out, F.mish(x))
    ours = x.clone().requires_grad_()
    ref = x.clone().requires_grad_()
    grad = torch.randn(2, 7, 5, 9)  # contiguous either way
    mish(ours).backward(grad)
    F.mish(ref).backward(grad)
    torch.testing.assert_close(ours.grad, ref.grad)


def test_non_dense_input():
    x = torch.randn(6, 8)[:, ::2]  # a strided view
    torch.testing.assert_close(mish(x), F.mish(x))


def test_empty():
    x = torch.empty(0, 3, requires_grad=True)
    out = mish(x)
    assert out.shape == (0, 3)
    out.sum().backward()
    assert x.grad.shape == (0, 3)


def test_built_from_act_cfg():
    from mmengine.registry import MODELS as ROOT_MODELS
    from mmengine.registry import DefaultScope

    # in MMDetection's registry (a runner or init_detector sets its scope),
    # not in MMEngine's root registry (importing the plugin leaves it
    # alone: tests/test_import_inert.py)
    assert 'CBNetMish' not in ROOT_MODELS.module_dict
    with DefaultScope.overwrite_default_scope('mmdet'):
        layer = build_activation_layer(dict(type='CBNetMish'))
    assert isinstance(layer, CBNetMish)
    x = torch.randn(3, 4)
    torch.testing.assert_close(layer(x), F.mish(x))
