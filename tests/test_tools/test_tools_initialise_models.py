"""Every tool that builds a model to train or time it initialises it.

``MODELS.build`` leaves every layer at PyTorch's default initialisation;
the heads' own (the Cascade RPN's focal prior p = 0.01, normal(0, 0.01)
convolutions, zero-initialised layers) only runs in ``init_weights()``.
Without it the CRPN's objectness starts at p ~ 0.5: a focal loss of ~26
whose bias gradient alone exceeds the clip norm. The check: the stage-2
objectness bias of the built model is the focal prior.
"""
import glob
import math
import os.path as osp

import pytest
import torch
from mmengine.config import Config

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
PRIOR_BIAS = -math.log((1 - 0.01) / 0.01)


def assert_focal_prior(rpn_head):
    bias = rpn_head.stages[1].rpn_cls.bias.detach()
    torch.testing.assert_close(bias, torch.full_like(bias, PRIOR_BIAS))


def test_fuzz_inputs_initialises_the_demo_model(cityscapes_like_root):
    from cbnet_lab import fuzz_inputs
    model, _ = fuzz_inputs.build(cityscapes_like_root, (64, 32))
    assert_focal_prior(model.rpn_head)


def test_build_detector_initialises_the_detector():
    """benchmark.py and profile_model.py build through this function."""
    from cbnet_lab import benchmark as B
    model = B.build_detector(Config.fromfile(DEMO))
    assert_focal_prior(model.rpn_head)


#: Tools that call MODELS.build for losses only (no layers to initialise):
#: none since the mask-loss benchmark's losses are built in
#: cbnet_lab/component_benchmark.py, beside the MiT it initialises.
LOSSES_ONLY = set()


@pytest.mark.parametrize(
    'path', sorted(
        glob.glob(osp.join(ROOT, 'tools', '**', '*.py'), recursive=True) +
        glob.glob(osp.join(ROOT, 'projects', '*', 'tools', '**', '*.py'),
                  recursive=True) +
        glob.glob(osp.join(ROOT, 'cbnet_lab', '**', '*.py'),
                  recursive=True)),
    ids=lambda p: osp.relpath(p, ROOT))
def test_no_tool_builds_a_model_without_initialising_it(path):
    """A tool (or lab module) calling ``MODELS.build`` must also call
    ``init_weights()``
    (tools that build through ``build_detector`` never call
    ``MODELS.build`` themselves), unless it builds losses only."""
    with open(path) as f:
        source = f.read()
    if 'MODELS.build(' not in source \
            or osp.relpath(path, ROOT) in LOSSES_ONLY:
        return
    assert 'init_weights()' in source, (
            f'{osp.relpath(path, ROOT)} builds a model with MODELS.build '
            'but never calls init_weights()')
