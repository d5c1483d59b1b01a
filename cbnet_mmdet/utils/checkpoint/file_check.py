"""Refuse a file that is not a PyTorch checkpoint, naming it.

``torch.load`` on an image (a PNG passed as the checkpoint by mistake)
fails with an unpickling error that advises turning ``weights_only`` off,
which would let a file run code, and that is never the fix. MMEngine reads
every local checkpoint through the loader registered for local paths in
:class:`mmengine.runner.CheckpointLoader` (``init_detector``,
``DetInferencer``, ``load_from``, ``Pretrained``);
:func:`load_local_checkpoint` is that loader with the file checked
first. It is registered (MMEngine's ``CheckpointLoader.register_scheme``)
when ``cbnet_mmdet`` is imported, i.e. by any of our configs'
``custom_imports``.
"""
import os.path as osp
import pickle
import re
import zipfile

import torch
from mmengine.runner import CheckpointLoader

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


def check_checkpoint_file(filename: str) -> None:
    """Raise a clear error when ``filename`` is not a ``torch.save`` file.

    Only the file's size and first bytes are read (and, for a zip archive,
    its directory at the end), so this is cheap on a large checkpoint. The
    one check behind every checkpoint the project reads: MMEngine's local
    loader (:func:`load_local_checkpoint`) and the training-time reader
    :func:`cbnet_mmdet.utils.checkpoint.files.read_checkpoint`.

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


def load_local_checkpoint(filename: str, map_location=None):
    """MMEngine's local checkpoint loader, with the file checked first.

    Loads with ``torch.load``'s default (``weights_only=True`` in torch
    >= 2.6, with the allow-list of
    :mod:`cbnet_mmdet.utils.checkpoint.safe_globals`). A file that holds
    other Python objects is refused with an error that names the object,
    without torch's advice to load it with ``weights_only=False``.

    Args:
        filename (str): Local path (``~`` expanded).
        map_location: As for ``torch.load``.

    Returns:
        The loaded checkpoint.
    """
    filename = osp.expanduser(filename)
    check_checkpoint_file(filename)
    try:
        return torch.load(filename, map_location=map_location)
    except pickle.UnpicklingError as err:
        raise refused(filename, err) from None


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


def use_checked_local_loader() -> None:
    """Register :func:`load_local_checkpoint` for local paths (MMEngine's
    ``CheckpointLoader``; URLs and other schemes keep their loaders)."""
    CheckpointLoader.register_scheme(
        prefixes='', loader=load_local_checkpoint, force=True)
