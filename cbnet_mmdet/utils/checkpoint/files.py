"""Checkpoint files: checked reading, resuming, release and student export.

:func:`check_checkpoint_file` refuses a file that is not a PyTorch
checkpoint, naming it and what it looks like (``torch.load`` on a PNG
passed by mistake fails with advice to turn ``weights_only`` off, which is
never the fix). :func:`read_checkpoint` reads a checkpoint weights-only,
with MMEngine's allow-list in force only while it reads
(:func:`~cbnet_mmdet.utils.checkpoint.safe_globals.mmengine_safe_globals`),
and names the file and the problem when it is missing, empty, truncated,
foreign or no PyTorch file; :func:`resume_checkpoint` picks what
``--resume`` continues from (``last_checkpoint`` resolved inside the work
dir, the newest intact checkpoint when the latest is damaged, never one
that :data:`DIVERGENCE_RECORD` names as written after the weights went
bad). ``CBNetRunner`` and the project's tools call them; importing the
package registers nothing with MMEngine's ``CheckpointLoader``.

:func:`publish_checkpoint` follows MMDetection's
``tools/model_converters/publish_model.py`` (OpenMMLab, Apache-2.0): keep
only ``meta`` and ``state_dict``, save, and put the first 8 hex digits of
the file's SHA-256 into its name. Unlike that script it loads with
``weights_only`` (the project's allow-list), hashes in Python and renames
synchronously, so the returned path exists when it returns.

:func:`extract_detector` turns a CBNet-DD (``CBNetDistiller``) checkpoint
into a plain CBNet one: the ``student.`` (or ``teacher.``) weights without
their prefix, and the config embedded in ``meta['cfg']`` replaced by the
distiller's ``detector``, so that MMDetection's ``DetInferencer`` and
``init_detector`` load it like any detector checkpoint.
"""
import copy
import glob
import hashlib
import json
import os
import os.path as osp
import pickle
import re
import zipfile
from typing import Dict, List, Optional, Sequence, Tuple

import torch
from mmengine.config import Config
from mmengine.runner import CheckpointLoader

from .safe_globals import mmengine_safe_globals

#: How a file written by ``torch.save`` starts: a zip archive (the format
#: since torch 1.6) or a pickle (protocol 2+, the legacy format).
CHECKPOINT_MAGIC = (b'PK\x03\x04', b'\x80')
#: Leading bytes of files people pass by mistake, for the message.
KNOWN_FORMATS = ((b'\x89PNG', 'a PNG image'), (b'\xff\xd8\xff', 'a JPEG '
                 'image'), (b'GIF8', 'a GIF image'), (b'BM', 'a BMP image'),
                 (b'{', 'a JSON file'), (b'#', 'a text / Python file'),
                 (b'%PDF', 'a PDF'))
#: What a checkpoint is, in messages.
WHAT_FITS = ('a .pth file written by torch.save (tools/train.py writes '
             'them into the work dir)')


class DivergedRunError(ValueError):
    """``--resume`` of a run that diverged, with no clean checkpoint."""


def check_checkpoint_file(filename: str) -> None:
    """Raise a clear error when ``filename`` is not a ``torch.save`` file.

    Only the file's size and first bytes are read (and, for a zip archive,
    its directory at the end), so this is cheap on a large checkpoint. The
    one check behind every checkpoint the project reads
    (:func:`read_checkpoint`).

    Args:
        filename (str): Local path.

    Raises:
        FileNotFoundError: no such file.
        ValueError: the file is empty, a truncated zip archive (an
            interrupted save or copy), or does not start like a file
            ``torch.save`` writes (the message names what it looks like).
    """
    if not osp.isfile(filename):
        raise FileNotFoundError(f'checkpoint not found: {filename}')
    size = osp.getsize(filename)
    if size == 0:
        raise ValueError(f'checkpoint {filename} is empty (0 bytes): an '
                         f'interrupted save? A checkpoint is {WHAT_FITS}')
    with open(filename, 'rb') as f:
        head = f.read(8)
    if head.startswith(CHECKPOINT_MAGIC[0]):
        if not zipfile.is_zipfile(filename):
            raise ValueError(
                f'checkpoint {filename} is truncated or damaged ({size} '
                f'bytes, no zip directory at its end): an interrupted save '
                f'or copy? Use an earlier checkpoint')
        return
    if head.startswith(CHECKPOINT_MAGIC[1]):
        return
    looks = next((name for magic, name in KNOWN_FORMATS
                  if head.startswith(magic)), None)
    what = f'it looks like {looks}' if looks else \
        f'it starts with {head[:4]!r}, neither a zip archive nor a pickle'
    raise ValueError(
        f'{filename} is not a PyTorch checkpoint ({what}); a checkpoint '
        f'is {WHAT_FITS}. Did you swap the image and the checkpoint '
        f'arguments?')


#: Written into the work dir when training stops on diverged weights:
#: which checkpoints were saved after they went bad (never resumed).
DIVERGENCE_RECORD = 'diverged.json'
#: What a published checkpoint keeps (MMDetection's default).
PUBLISH_KEYS = ('meta', 'state_dict')
#: Bytes read at a time when hashing.
_CHUNK = 1 << 20


def read_checkpoint(path: str, mmap: bool = False) -> dict:
    """Read a local checkpoint file, naming the file and the problem.

    Loads with ``torch.load(weights_only=True)`` and MMEngine's allow-list
    in force for this call only
    (:func:`~cbnet_mmdet.utils.checkpoint.safe_globals.mmengine_safe_globals`);
    never with ``weights_only=False``. Meant for every place that reads a
    checkpoint the user names (``--resume``, ``load_from``, the work dir's
    latest, inference tools): instead of torch's ``PytorchStreamReader``
    error, ``KeyError: 101`` (a text file) and the like, one error says
    which file and what is wrong.

    Args:
        path (str): Local file.
        mmap (bool): Map the tensors' storage instead of reading it (cheap
            check of a large file; the result's tensors stay valid).

    Returns:
        dict: The checkpoint's top level (MMEngine's ``meta``,
        ``state_dict``, ... or a bare state dict).

    Raises:
        FileNotFoundError: No such file.
        ValueError: Empty file, truncated or damaged zip archive (an
            interrupted save), not a PyTorch file at all, or a top level
            that is not a dict.
        pickle.UnpicklingError: The file asks for code outside the
            allow-list (refused, as a malicious file must be).
    """
    check_checkpoint_file(path)
    with open(path, 'rb') as f:
        head = f.read(2)
    try:
        with mmengine_safe_globals():
            checkpoint = torch.load(path, map_location='cpu',
                                    weights_only=True,
                                    mmap=mmap and head[:2] == b'PK')
    except pickle.UnpicklingError as err:
        raise refused(path, err) from None
    except (RuntimeError, EOFError, OSError, ValueError) as err:
        raise ValueError(f'checkpoint {path} is truncated or damaged: '
                         f'{err}') from err
    if not isinstance(checkpoint, dict):
        raise ValueError(f'{path} holds a {type(checkpoint).__name__}, not '
                         f'a checkpoint dict')
    return checkpoint


def refused(filename: str,
            err: pickle.UnpicklingError) -> pickle.UnpicklingError:
    """The error for a file that weights-only loading refused: it names
    the file and the object, and drops torch's advice to load it with
    ``weights_only=False`` (which would let the file run code).

    Args:
        filename (str): The checkpoint.
        err (pickle.UnpicklingError): torch's error.

    Returns:
        pickle.UnpicklingError: To raise.
    """
    found = re.search(r'Unsupported global: GLOBAL (\S+)', str(err))
    what = (f'the Python object {found.group(1)}'
            if found else 'Python objects')
    return pickle.UnpicklingError(
        f'checkpoint {filename} holds {what}, which torch.load\'s '
        f'weights-only loading refuses: it reads tensors, Python '
        f'values and the MMEngine log objects cbnet_mmdet allows '
        f'(cbnet_mmdet/utils/checkpoint/safe_globals.py), nothing '
        f'that could run code. A checkpoint written by tools/train.py '
        f'holds nothing else; for a file from elsewhere, ask for one '
        f'saved as torch.save(dict(state_dict=model.state_dict()))')


def unwrap_state_dict(checkpoint: Dict) -> Dict[str, torch.Tensor]:
    """The weights of a checkpoint dict (``state_dict``/``model``/itself)."""
    if not isinstance(checkpoint, dict):
        raise TypeError('expected a checkpoint dict, got '
                        f'{type(checkpoint).__name__}')
    for key in ('state_dict', 'model'):
        if isinstance(checkpoint.get(key), dict):
            return checkpoint[key]
    return checkpoint


def check_resumable(checkpoint: dict, path: str) -> None:
    """Raise ``ValueError`` naming ``path`` unless ``checkpoint`` (read with
    :func:`read_checkpoint`) is a training checkpoint MMEngine can resume:
    ``meta`` with ``epoch`` and ``iter``, a ``state_dict`` dict."""
    if 'meta' not in checkpoint or 'state_dict' not in checkpoint:
        what = 'a bare state dict' if checkpoint and all(
            isinstance(v, torch.Tensor) for v in checkpoint.values()) \
            else f'a dict with keys {sorted(checkpoint)[:6]}'
        raise ValueError(
            f'{path} cannot be resumed: it is {what}, not a training '
            f'checkpoint (no `meta` with epoch and iteration, or no '
            f'`state_dict`). --resume continues a run of tools/train.py; '
            f'to start from these weights use load_from (--cfg-options '
            f'load_from={path})')
    meta = checkpoint['meta']
    if not isinstance(meta, dict) or not all(
            isinstance(meta.get(k), int) for k in ('epoch', 'iter')) or \
            not isinstance(checkpoint['state_dict'], dict):
        raise ValueError(
            f'{path} cannot be resumed: its `meta` has no integer epoch '
            f'and iter, or its `state_dict` is not a dict (a published or '
            f'exported checkpoint? use it as load_from)')


def checkpoint_problem(path: str) -> str:
    """Why ``path`` cannot be resumed ('' when it can); reads it with
    ``mmap`` (cheap)."""
    try:
        check_resumable(read_checkpoint(path, mmap=True), path)
    except (OSError, ValueError, pickle.UnpicklingError) as err:
        return str(err)
    return ''


def intact_checkpoints(work_dir: str) -> List[Tuple[str, int]]:
    """The resumable ``*.pth`` files of a work dir, newest first.

    Args:
        work_dir (str): Where ``CheckpointHook`` writes.

    Returns:
        list[tuple[str, int]]: ``(path, meta iter)`` sorted by iteration,
        then modification time, newest first; damaged, foreign and
        unreadable files are left out.
    """
    found = []
    for path in glob.glob(osp.join(glob.escape(work_dir), '*.pth')):
        try:
            checkpoint = read_checkpoint(path, mmap=True)
            check_resumable(checkpoint, path)
        except (OSError, ValueError, pickle.UnpicklingError):
            continue
        found.append((path, checkpoint['meta']['iter'],
                      osp.getmtime(path)))
    found.sort(key=lambda item: (item[1], item[2]), reverse=True)
    return [(path, it) for path, it, _ in found]


def last_checkpoint_in(work_dir: str) -> Tuple[Optional[str], str]:
    """The checkpoint ``work_dir/last_checkpoint`` names, as a path inside
    ``work_dir``.

    MMEngine writes an absolute path there. When the work dir was moved
    or copied, that path names the ORIGINAL folder's file (or nothing);
    this returns the file of the same name in ``work_dir`` instead.

    Returns:
        tuple[str | None, str]: The path (None: no ``last_checkpoint``
        file, or it names nothing in ``work_dir``) and a note for the log
        ('' when the recorded path was used as it is).
    """
    record = osp.join(work_dir, 'last_checkpoint')
    if not osp.isfile(record):
        return None, ''
    with open(record) as f:
        recorded = f.read().strip()
    if not recorded:
        return None, f'{record} is empty'
    here = recorded if osp.isabs(recorded) else osp.join(work_dir, recorded)
    local = osp.join(work_dir, osp.basename(recorded))
    if osp.realpath(osp.dirname(here)) == osp.realpath(work_dir):
        return here, ''
    if osp.isfile(local):
        return local, (f'{record} names {recorded}, outside the work dir '
                       f'(moved or copied?): using {local}')
    return None, (f'{record} names {recorded}, which is not in the work '
                  f'dir {work_dir}')


def _file_id(path: str) -> Dict[str, object]:
    """Size and SHA-256 of a file: a checkpoint is named by its content,
    so that a copied work dir (``cp -r`` gives the files new times) keeps
    its record, and a file written again under the same name is another
    file."""
    return dict(size=os.stat(path).st_size, sha256=sha256_file(path))


def _same_file(path: str, ident) -> bool:
    """Whether ``path`` is the file a record's ``ident`` names. Records
    written before checkpoints were named by content hold ``[size,
    mtime_ns]`` and are compared that way."""
    if not osp.isfile(path):
        return False
    if isinstance(ident, dict):
        return (os.stat(path).st_size == ident.get('size')
                and sha256_file(path) == ident.get('sha256'))
    stat = os.stat(path)
    return [stat.st_size, stat.st_mtime_ns] == list(ident)


def record_divergence(work_dir: str, message: str,
                      unsafe: Sequence[str]) -> str:
    """Write :data:`DIVERGENCE_RECORD` into ``work_dir``: training stopped
    with ``message`` and the checkpoints ``unsafe`` hold weights written
    after they went bad (``CBNetNonFiniteLossHook`` calls it as it stops).
    Each file is recorded by its size and SHA-256.

    Returns:
        str: The record's path.
    """
    record = osp.join(work_dir, DIVERGENCE_RECORD)
    files = {osp.basename(p): _file_id(p) for p in unsafe if osp.isfile(p)}
    with open(record, 'w') as f:
        json.dump(dict(error=message, unsafe=files), f, indent=1)
    return record


def diverged_checkpoints(work_dir: str) -> Tuple[List[str], str]:
    """The checkpoints of ``work_dir`` that its :data:`DIVERGENCE_RECORD`
    names as written after the weights went bad, and still the same files
    by content (one written again since, by a run resumed from a clean
    checkpoint, is not; a copy of the work dir keeps them), with the
    record's error ('' without a record)."""
    record = osp.join(work_dir, DIVERGENCE_RECORD)
    if not osp.isfile(record):
        return [], ''
    try:
        with open(record) as f:
            content = json.load(f)
        files, error = dict(content['unsafe']), str(content['error'])
    except (ValueError, KeyError, TypeError) as err:
        raise ValueError(f'{record} is damaged ({err}): it says which '
                         f'checkpoints hold diverged weights; delete it '
                         f'only to resume from any of them') from err
    unsafe = [
        osp.join(work_dir, name) for name, ident in files.items()
        if _same_file(osp.join(work_dir, name), ident)
    ]
    return unsafe, error.split('. ')[0]


def _went_bad(error: str) -> str:
    return (f'written after the weights went bad (the run stopped: '
            f'{error})')


def _intact_hint(work_dir: str, exclude: Sequence[str]) -> str:
    bad = {osp.realpath(p) for p in exclude}
    intact = [p for p, _ in intact_checkpoints(work_dir)
              if osp.realpath(p) not in bad]
    return (f' (newest intact checkpoint of {work_dir}: {intact[0]})'
            if intact else '')


def diverged_problem(path: str) -> str:
    """Why ``path`` must not be loaded as a starting point: '' unless the
    :data:`DIVERGENCE_RECORD` of its folder names it (by content) as
    written after the weights went bad; then the reason, with the newest
    intact clean checkpoint of that folder, if any. ``CBNetRunner``
    refuses such a file for ``load_from`` as for ``--resume``."""
    if '://' in path or not osp.isfile(path):
        return ''
    work_dir = osp.dirname(osp.abspath(path))
    diverged, error = diverged_checkpoints(work_dir)
    if osp.realpath(path) not in {osp.realpath(p) for p in diverged}:
        return ''
    return _went_bad(error) + _intact_hint(work_dir, diverged)


def resume_checkpoint(work_dir: str,
                      path: Optional[str] = None) -> Tuple[Optional[str],
                                                           List[str]]:
    """The checkpoint to resume from, checked, with what to log.

    Args:
        work_dir (str): The run's work dir.
        path (str, optional): The checkpoint asked for (``--resume PATH``);
            None: the work dir's latest (``--resume``).

    Returns:
        tuple[str | None, list[str]]: The checkpoint (None: nothing to
        resume from in the work dir, train from scratch) and notes for
        the log (a moved work dir, a damaged or diverged latest
        checkpoint and the fallback taken).

    A checkpoint the work dir's :data:`DIVERGENCE_RECORD` names (written
    after the weights went bad, before ``CBNetNonFiniteLossHook`` stopped
    the run) is never resumed: ``--resume`` falls back to the newest
    clean one, saying so, and refuses when there is none.

    Raises:
        FileNotFoundError / ValueError / pickle.UnpicklingError: ``path``
            was given and cannot be resumed (named, with the problem and
            the newest intact checkpoint of the work dir, if any).
        DivergedRunError: the run diverged and no checkpoint of the work
            dir is clean.
    """
    if path is not None and '://' in path:
        return path, []  # remote: MMEngine's loader
    diverged, error = diverged_checkpoints(work_dir)
    bad = {osp.realpath(p) for p in diverged}
    went_bad = _went_bad(error)
    if path is not None:
        problem = checkpoint_problem(path)
        if problem or osp.realpath(path) in bad:
            problem = (problem or went_bad) + _intact_hint(
                work_dir, [*diverged, path])
        else:  # a diverged checkpoint of another run's folder
            problem = diverged_problem(path)
        if problem:
            kind = FileNotFoundError if not osp.isfile(path) else \
                pickle.UnpicklingError if 'refuse' in problem else ValueError
            raise kind(f'--resume {path}: {problem}')
        return path, []
    latest, note = last_checkpoint_in(work_dir)
    notes = [note] if note else []
    if latest is not None:
        problem = checkpoint_problem(latest)
        if not problem and osp.realpath(latest) in bad:
            problem = f'{latest} was {went_bad}'
        if not problem:
            return latest, notes
        notes.append(f'latest checkpoint unusable: {problem}')
    intact = [(p, it) for p, it in intact_checkpoints(work_dir)
              if osp.realpath(p) not in bad]
    if intact:
        if latest is not None or note or bad:
            which = 'last clean' if bad else 'newest intact'
            notes.append(f'falling back to the {which} checkpoint of the '
                         f'work dir: {intact[0][0]} (iteration '
                         f'{intact[0][1]})')
        return intact[0][0], notes
    if bad:
        raise DivergedRunError(
            f'cannot resume {work_dir}: the run stopped ({error}) and its '
            f'checkpoints {", ".join(sorted(diverged))} were written after '
            f'the weights went bad; no checkpoint of it is clean: start '
            f'again without --resume (lower the lr or check the data)')
    if latest is not None or note:
        notes.append(f'no intact checkpoint in {work_dir}: training from '
                     f'scratch')
    return None, notes


def load_checkpoint_file(path: str) -> dict:
    """Load a checkpoint file (weights-only, allow-listed globals).

    Args:
        path (str): Local path or URL of an MMEngine checkpoint.

    Returns:
        dict: The checkpoint (``state_dict``, ``meta``, ...).

    Raises:
        FileNotFoundError: a local ``path`` that does not exist.
        ValueError: the file is damaged or not a checkpoint (see
            :func:`read_checkpoint`) or holds no ``state_dict`` dict.
    """
    if '://' in path:
        with mmengine_safe_globals():
            checkpoint = CheckpointLoader.load_checkpoint(
                path, map_location='cpu')
    else:
        checkpoint = read_checkpoint(path)
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
