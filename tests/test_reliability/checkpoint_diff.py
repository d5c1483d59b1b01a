"""Where two checkpoints differ: the paths of their nested structures
(weights, optimiser, schedulers, random states) whose values are not
equal, for the resume and distributed training tests."""
import torch


def differences(a, b, path='') -> list:
    """Paths at which two nested checkpoint structures differ."""
    if isinstance(a, torch.Tensor):
        return [] if torch.equal(a, b) else [path]
    if isinstance(a, dict):
        if a.keys() != b.keys():
            return [f'{path}: keys {sorted(a.keys() ^ b.keys())}']
        return [d for k in a for d in differences(a[k], b[k], f'{path}.{k}')]
    if isinstance(a, (list, tuple)):
        if len(a) != len(b):
            return [f'{path}: lengths {len(a)} != {len(b)}']
        return [
            d for i, (x, y) in enumerate(zip(a, b))
            for d in differences(x, y, f'{path}[{i}]')
        ]
    return [] if a == b else [f'{path}: {a!r} != {b!r}']
