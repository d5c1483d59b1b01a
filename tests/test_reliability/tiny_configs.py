"""The demo config (and a CBNet-DD variant) shrunk for CPU tests.

The demo config (``configs/demo/...``) with the tiny generated dataset,
64x128 images, 2 images per batch, no validation, a checkpoint every
epoch, fixed seed. Written to a file so ``tools/train.py`` /
``tools/dist_train.sh`` can run it in a subprocess.
"""
import os
import os.path as osp
import subprocess
import sys

from mmengine.config import Config

REPO = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
HERE = osp.dirname(osp.abspath(__file__))
# one loader of the tools/ scripts for all tests: tests/test_tools' helper
# (tests/conftest.py puts its folder on sys.path)
from tool_helpers import load_tool  # noqa: E402,F401  (re-exported)
DEMO = osp.join(REPO, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
#: (w, h) the 128x256 fixture images are resized to, for speed.
SCALE = (128, 64)


def train_pipeline(paired: bool = False) -> list:
    load = 'CBNetLoadPairedImageFromFile' if paired else \
        'CBNetLoadImageFromFile'
    return [
        dict(type=load),
        dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
        dict(type='Resize', scale=SCALE, keep_ratio=True),
        dict(type='RandomFlip', prob=0.5),
        dict(type='PackDetInputs'),
    ]


def demo_cfg(data_root: str,
             max_epochs: int = 2,
             batch_size: int = 2,
             custom_hooks=None,
             distill: bool = False,
             extra_imports=()) -> Config:
    """The shrunk demo config.

    Args:
        data_root (str): The ``cityscapes_like_root`` fixture.
        max_epochs (int): Epochs (2 iterations each with the fixture's 3
            non-empty training images and ``batch_size=2``).
        batch_size (int): Images per process and iteration.
        custom_hooks (list[dict], optional): Defaults to the reliability
            hooks (``CBNetRNGStateHook``, ``CBNetNonFiniteLossHook``,
            ``CBNetCheckpointReportHook``).
        distill (bool): Wrap the detector in ``CBNetDistiller`` with
            ``CBNetTeacherEMAHook`` on foggy/clear pairs (CBNet-DD).
        extra_imports (Sequence[str]): Modules added to ``custom_imports``
            (e.g. ``'helper_hooks'`` from this folder).

    Returns:
        Config: Ready to ``dump`` or to give to ``Runner.from_cfg``.
    """
    cfg = Config.fromfile(DEMO)
    if custom_hooks is None:
        custom_hooks = [
            dict(type='CBNetRNGStateHook'),
            dict(type='CBNetNonFiniteLossHook', param_interval=1),
            dict(type='CBNetCheckpointReportHook'),
        ]
    dataset = cfg.train_dataloader.dataset.dataset
    dataset.data_root = data_root
    dataset.pipeline = train_pipeline(distill)
    cfg.train_dataloader.update(
        batch_size=batch_size, num_workers=0, persistent_workers=False)
    model = cfg.model
    model.test_cfg.rpn.update(nms_pre=200, max_per_img=50)
    model.train_cfg.rpn_proposal.update(nms_pre=200, max_per_img=50)
    for rcnn in model.train_cfg.rcnn:
        rcnn.sampler.num = 32
    if distill:
        detector = model
        preprocessor = detector.pop('data_preprocessor')
        preprocessor.type = 'CBNetPairedDataPreprocessor'
        model = dict(type='CBNetDistiller', detector=detector,
                     data_preprocessor=preprocessor)
        cfg.train_dataloader.dataset.dataset.update(
            type='CBNetPairedFoggyDataset', beta=0.02)
        custom_hooks = custom_hooks + [
            dict(type='CBNetTeacherEMAHook', momentum=0.9)
        ]
    cfg.merge_from_dict(
        dict(
            custom_hooks=custom_hooks,
            train_cfg=dict(max_epochs=max_epochs, val_interval=100),
            default_hooks=dict(
                checkpoint=dict(interval=1, max_keep_ckpts=-1,
                                save_best=None),
                logger=dict(interval=1)),
            randomness=dict(seed=0)))
    for key in ('val_dataloader', 'val_evaluator', 'val_cfg',
                'test_dataloader', 'test_evaluator', 'test_cfg'):
        cfg[key] = None
    # BN running statistics differ between ranks unless averaged (MMEngine's
    # DDP wrapper does not broadcast buffers): docs/reliability.md
    cfg.default_hooks.setdefault('sync_buffers',
                                 dict(type='SyncBuffersHook'))
    cfg.model = model
    cfg.custom_imports = dict(
        imports=['cbnet_mmdet', *extra_imports], allow_failed_imports=False)
    return cfg


def write_cfg(cfg: Config, path: str) -> str:
    cfg.dump(path)
    return path


def subprocess_env() -> dict:
    """Environment of a training subprocess: repo and this folder
    importable, one thread per process (the CI has 2 cores)."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(
        [REPO, HERE] + [p for p in [env.get('PYTHONPATH')] if p])
    env.setdefault('OMP_NUM_THREADS', '1')
    env['PYTHONWARNINGS'] = 'ignore'
    return env


def train_cmd(cfg_path: str, work_dir: str, *args: str) -> list:
    return [sys.executable, osp.join(REPO, 'tools', 'train.py'), cfg_path,
            '--work-dir', work_dir, *args]


def run(cmd, timeout: float = 240, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(
        cmd, cwd=REPO, env=subprocess_env(), capture_output=True, text=True,
        timeout=timeout, **kwargs)
