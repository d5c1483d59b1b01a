"""Distributed launches (torchrun, ``tools/dist_*.sh``) on CPU-only
machines, for ``tools/train.py`` and ``tools/test.py``."""
import torch
import torch.distributed as torch_dist
from mmengine.config import Config


def use_gloo_on_cpu(cfg: Config) -> None:
    """Let a distributed launch run on CPU-only machines.

    MMEngine's ``init_dist`` calls ``torch.cuda.set_device`` and MMDet's
    runtime asks for NCCL, and the DDP wrapper gets ``device_ids=[rank]``:
    all three need a GPU. Without one, use gloo and a CPU DDP wrapper
    (``device_ids=None``); the process group itself is created in
    :func:`init_gloo_process_group`.

    Args:
        cfg (Config): The run's config, modified in place.
    """
    cfg.setdefault('env_cfg', {}).setdefault('dist_cfg', {})
    cfg.env_cfg.dist_cfg['backend'] = 'gloo'
    wrapper = cfg.get('model_wrapper_cfg') or dict(
        type='MMDistributedDataParallel')
    wrapper['device_ids'] = None
    cfg.model_wrapper_cfg = wrapper


def init_gloo_process_group(cfg: Config) -> None:
    """Create the gloo process group from torchrun's environment (CPU only;
    MMEngine then finds it initialised and skips its CUDA set-up).

    Args:
        cfg (Config): The run's config (``launcher``).
    """
    if cfg.launcher == 'pytorch' and not torch.cuda.is_available() \
            and not torch_dist.is_initialized():
        torch_dist.init_process_group(backend='gloo')
