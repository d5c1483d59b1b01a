"""Helpers of the tool smoke tests: load a script of ``tools/`` (or of a
project's ``tools/``) as a module (the tools are not a package); a
checkpoint of the demo model; a source trunk with non-trivial BN
statistics (the weight converters' tests); the arguments of a tiny
``compare_recipes.py`` run."""
import importlib.util
import os.path as osp

REPO = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
DEMO = osp.join(REPO, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
#: compare_recipes.py at tiny sizes: one seed, 2 iterations of 2 images,
#: data loaded in process.
FAST = ['--seeds', '0', '--iters', '2', '--batch-size', '2',
        '--num-workers', '0', '--warmup-iters', '1']
#: ``--cfg-options`` that test in process too.
TEST_IN_PROCESS = ['test_dataloader.num_workers=0',
                   'test_dataloader.persistent_workers=False']


def tool_file(relpath: str) -> str:
    """``tools/{relpath}``, or ``{relpath}`` from the repository root for a
    project's command line (``projects/NAME/tools/...``)."""
    if relpath.startswith('projects/'):
        return osp.join(REPO, relpath)
    return osp.join(REPO, 'tools', relpath)


def load_tool(relpath: str):
    """Import a command line under a private module name.

    Args:
        relpath (str): Path under ``tools/``, e.g.
            ``'analysis_tools/benchmark_mask_loss.py'``, or a project's
            from the repository root, e.g.
            ``'projects/peer_dehaze/tools/train_dehazer.py'``.
    """
    name = 'cbnet_tools_' + relpath.replace('/', '_')[:-3]
    spec = importlib.util.spec_from_file_location(name, tool_file(relpath))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def demo_checkpoint(path: str) -> str:
    """Save the demo model, seeded and initialised (random weights), as a
    checkpoint at ``path``; returns ``path``."""
    import torch
    from mmdet.registry import MODELS
    from mmengine.config import Config
    from mmengine.registry import init_default_scope
    init_default_scope('mmdet')
    torch.manual_seed(0)
    model = MODELS.build(Config.fromfile(DEMO).model)
    model.init_weights()
    torch.save(dict(state_dict=model.state_dict(), meta=dict()), path)
    return path


def with_random_bn(model):
    """``model`` in eval mode with every BatchNorm's statistics and affine
    parameters drawn away from their defaults (seed them first), so that a
    converter that swaps two BNs gives other features."""
    from torch import nn
    for m in model.modules():
        if isinstance(m, nn.BatchNorm2d):
            m.running_mean.uniform_(-0.1, 0.1)
            m.running_var.uniform_(0.5, 1.5)
            m.weight.data.uniform_(0.5, 1.5)
            m.bias.data.uniform_(-0.1, 0.1)
    return model.eval()
