"""use_channels_last: the one policy of the mask head and neck (CPU
inference only by default)."""
import pytest
import torch

from cbnet_mmdet.models.utils import use_channels_last


@pytest.mark.parametrize('setting, device, grad, expected', [
    (None, 'cpu', False, True),
    (None, 'cpu', True, False),  # training: NCHW backward is faster
    (None, 'meta', False, False),  # any non-CPU device keeps NCHW
    (True, 'meta', True, True),
    (True, 'cpu', True, True),
    (False, 'cpu', False, False),
])
def test_use_channels_last(setting, device, grad, expected):
    x = torch.empty(1, 2, 3, 4, device=device)
    with torch.set_grad_enabled(grad):
        assert use_channels_last(setting, x) is expected
