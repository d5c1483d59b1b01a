"""use_channels_last: the one CPU-only policy of the mask head and neck."""
import pytest
import torch

from cbnet_mmdet.models.utils import use_channels_last


@pytest.mark.parametrize('setting, device, expected', [
    (None, 'cpu', True),
    (None, 'meta', False),  # any non-CPU device keeps NCHW by default
    (True, 'meta', True),
    (False, 'cpu', False),
])
def test_use_channels_last(setting, device, expected):
    x = torch.empty(1, 2, 3, 4, device=device)
    assert use_channels_last(setting, x) is expected
