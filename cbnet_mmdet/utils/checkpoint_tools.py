"""Checkpoint files for release: publish (strip + hash) and student export.

:func:`publish_checkpoint` follows MMDetection's
``tools/model_converters/publish_model.py`` (OpenMMLab, Apache-2.0): keep
only ``meta`` and ``state_dict``, save, and put the first 8 hex digits of
the file's SHA-256 into its name. Unlike that script it loads with
``weights_only`` (the project's allow-list, see
:mod:`cbnet_mmdet.utils.checkpoint_safe_globals`), hashes in Python and
renames synchronously, so the returned path exists when it returns.

:func:`extract_detector` turns a CBNet-DD (``CBNetDistiller``) checkpoint
into a plain CBNet one: the ``student.`` (or ``teacher.``) weights without
their prefix, and the config embedded in ``meta['cfg']`` replaced by the
distiller's ``detector``, so that MMDetection's ``DetInferencer`` and
``init_detector`` load it like any detector checkpoint.
"""
import copy
import hashlib
import os
import os.path as osp
from typing import Sequence

import torch
from mmengine.config import Config
from mmengine.runner import CheckpointLoader

#: What a published checkpoint keeps (MMDetection's default).
PUBLISH_KEYS = ('meta', 'state_dict')
#: Bytes read at a time when hashing.
_CHUNK = 1 << 20


def load_checkpoint_file(path: str) -> dict:
    """Load a checkpoint file (weights-only, allow-listed globals).

    Args:
        path (str): Local path or URL of an MMEngine checkpoint.

    Returns:
        dict: The checkpoint (``state_dict``, ``meta``, ...).

    Raises:
        FileNotFoundError: a local ``path`` that does not exist.
        ValueError: the file holds no ``state_dict`` dict.
    """
    if '://' not in path and not osp.isfile(path):
        raise FileNotFoundError(f'checkpoint not found: {path}')
    checkpoint = CheckpointLoader.load_checkpoint(path, map_location='cpu')
    if not isinstance(checkpoint, dict) or not isinstance(
            checkpoint.get('state_dict'), dict):
        raise ValueError(f'{path} is not an MMEngine checkpoint (no '
                         f'`state_dict` dict at the top level)')
    return checkpoint


def sha256_file(path: str) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, 'rb') as f:
        for block in iter(lambda: f.read(_CHUNK), b''):
            digest.update(block)
    return digest.hexdigest()


def save_hashed(checkpoint: dict, out_file: str) -> str:
    """Save ``checkpoint`` and rename it ``{stem}-{sha256[:8]}.pth``.

    Args:
        checkpoint (dict): What to save.
        out_file (str): Requested path; a ``.pth`` suffix is replaced.

    Returns:
        str: The final path.
    """
    out_dir = osp.dirname(osp.abspath(out_file))
    os.makedirs(out_dir, exist_ok=True)
    torch.save(checkpoint, out_file)
    stem = out_file[:-4] if out_file.endswith('.pth') else out_file
    final = f'{stem}-{sha256_file(out_file)[:8]}.pth'
    os.replace(out_file, final)
    return final


def publish_checkpoint(in_file: str,
                       out_file: str,
                       save_keys: Sequence[str] = PUBLISH_KEYS) -> str:
    """Strip a training checkpoint for release and hash its name.

    Args:
        in_file (str): Checkpoint written by MMEngine's runner.
        out_file (str): Output path; the final name gets ``-{hash8}``.
        save_keys (Sequence[str]): Top-level keys kept (optimizer, message
            hub, schedulers, ... are dropped).

    Returns:
        str: The published file's path.
    """
    checkpoint = load_checkpoint_file(in_file)
    kept = {k: v for k, v in checkpoint.items() if k in save_keys}
    return save_hashed(kept, out_file)


def extract_detector(in_file: str,
                     out_file: str,
                     which: str = 'student',
                     hashed: bool = False) -> str:
    """Export the student (or EMA teacher) of a CBNet-DD checkpoint.

    Args:
        in_file (str): ``CBNetDistiller`` checkpoint (keys ``student.*`` and
            ``teacher.*``).
        out_file (str): Output path.
        which (str): ``'student'`` (evaluated by CBNet-DD's configs) or
            ``'teacher'``.
        hashed (bool): Put ``-{sha256[:8]}`` into the name as
            :func:`publish_checkpoint` does.

    Returns:
        str: The written file's path. It holds ``state_dict`` (plain
        detector keys) and ``meta`` (the input's, with ``cfg`` replaced by
        the detector's config when the input embeds one).

    Raises:
        ValueError: ``which`` is neither, or no ``{which}.`` key exists.
    """
    if which not in ('student', 'teacher'):
        raise ValueError(f"which must be 'student' or 'teacher', got "
                         f'{which!r}')
    checkpoint = load_checkpoint_file(in_file)
    prefix = which + '.'
    state_dict = {
        k[len(prefix):]: v
        for k, v in checkpoint['state_dict'].items() if k.startswith(prefix)
    }
    if not state_dict:
        sample = ', '.join(list(checkpoint['state_dict'])[:3])
        raise ValueError(
            f'{in_file} has no {prefix}* weights (not a CBNet-DD '
            f'checkpoint? its keys start: {sample})')
    meta = dict(checkpoint.get('meta') or {})
    if 'cfg' in meta:
        meta['cfg'] = detector_config(
            Config.fromstring(meta['cfg'], file_format='.py')).pretty_text
    meta['extracted_from'] = dict(file=osp.basename(in_file), which=which)
    out = dict(state_dict=state_dict, meta=meta)
    if hashed:
        return save_hashed(out, out_file)
    os.makedirs(osp.dirname(osp.abspath(out_file)), exist_ok=True)
    torch.save(out, out_file)
    return out_file


def detector_config(cfg: Config) -> Config:
    """The plain detector's config inside a CBNet-DD config.

    ``model`` becomes ``model.detector`` and the teacher-EMA hook is
    dropped; the rest (test pipeline, evaluators, visualizer) is kept. The
    paired training set stays as it is: the result is meant for testing
    and inference.

    Args:
        cfg (Config): A config whose ``model`` is a ``CBNetDistiller``.

    Returns:
        Config: A copy with the plain detector.

    Raises:
        ValueError: ``cfg.model`` has no ``detector``.
    """
    if 'detector' not in cfg.model:
        raise ValueError(
            f'the config\'s model ({cfg.model.get("type")}) has no '
            f'`detector`: not a CBNet-DD config')
    cfg = copy.deepcopy(cfg)
    cfg.model = cfg.model.detector
    hooks = [h for h in cfg.get('custom_hooks', [])
             if h.get('type') != 'CBNetTeacherEMAHook']
    cfg.custom_hooks = hooks
    return cfg
