"""The config of a weightless build: a detector config for the speed,
memory and FLOPs benchmarks and the profiler, nothing downloaded or
loaded, and the optimiser their timed training steps take.
"""
import os
from typing import Optional, Union

from mmengine.config import Config, ConfigDict


def strip_pretrained(cfg: Union[dict, list]) -> Union[dict, list]:
    """Copy of a (model) config with pretrained initialisation removed.

    Every ``init_cfg`` of type ``Pretrained`` (alone or in a list) becomes
    ``None`` and every ``pretrained=...`` key is dropped, at any depth.

    Args:
        cfg (dict | list): A model config (or part of one).

    Returns:
        dict | list: The config without pretrained initialisation.
    """

    def is_pretrained(init):
        inits = init if isinstance(init, (list, tuple)) else [init]
        return any(
            isinstance(i, dict) and i.get('type') == 'Pretrained'
            for i in inits)

    if isinstance(cfg, (list, tuple)):
        return type(cfg)(strip_pretrained(v) for v in cfg)
    if not isinstance(cfg, dict):
        return cfg
    out = type(cfg)() if isinstance(cfg, ConfigDict) else {}
    for key, value in cfg.items():
        if key == 'pretrained':
            continue
        if key == 'init_cfg' and is_pretrained(value):
            out[key] = None
            continue
        out[key] = strip_pretrained(value)
    return out


def load_benchmark_cfg(path: str,
                       cfg_options: Optional[dict] = None) -> Config:
    """Load a detector config for a weightless build on fixed inputs.

    Removes pretrained initialisation (:func:`strip_pretrained`),
    ``load_from``, and the data preprocessor's ``batch_augments`` (YOLOX's
    random multi-scale resize would change the measured input size), then
    applies ``cfg_options``.

    Args:
        path (str): Config file.
        cfg_options (dict, optional): Config keys to override, last.

    Returns:
        Config: The loaded, modified config.

    Raises:
        FileNotFoundError: ``path`` does not exist.
        KeyError: The config has no ``model``.
    """
    if not os.path.isfile(path):
        raise FileNotFoundError(f'config file not found: {path}')
    cfg = Config.fromfile(path)
    if 'model' not in cfg:
        raise KeyError(f'config {path} has no `model`')
    cfg.model = strip_pretrained(cfg.model)
    cfg.model.get('data_preprocessor', {}).pop('batch_augments', None)
    cfg.load_from = None
    if cfg_options:
        cfg.merge_from_dict(cfg_options)
    return cfg


def timing_optim_cfg(optim_cfg: Optional[dict], amp: bool = False) -> dict:
    """The optimiser of a timed training step: the config's own (SGD
    where it has none), AMP's wrapper with ``amp``, at a tiny lr, so the
    weights barely move between the timed steps."""
    cfg = dict(optim_cfg or dict(
        type='OptimWrapper', optimizer=dict(type='SGD', lr=1e-5)))
    if amp:
        cfg['type'] = 'AmpOptimWrapper'
    cfg['optimizer'] = dict(cfg['optimizer'], lr=1e-8)
    return cfg
