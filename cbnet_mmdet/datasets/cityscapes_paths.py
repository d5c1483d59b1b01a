"""File-name conventions of Cityscapes and Foggy Cityscapes.

Clear image::

    leftImg8bit/{split}/{city}/{stem}_leftImg8bit.png

Foggy image::

    leftImg8bit_foggy/{split}/{city}/{stem}_leftImg8bit_foggy_beta_{beta}.png

Annotations::

    gtFine/{split}/{city}/{stem}_gtFine_{instanceIds,labelIds}.png
    gtFine/{split}/{city}/{stem}_gtFine_polygons.json

``beta`` is the attenuation coefficient of the fog (0.005, 0.01 or 0.02 in
the released dataset); it is written as in the released file names.
"""
import os.path as osp
import re
from typing import Tuple

#: The attenuation coefficients released with Foggy Cityscapes.
FOGGY_BETAS = (0.005, 0.01, 0.02)

CLEAR_DIR = 'leftImg8bit'
FOGGY_DIR = 'leftImg8bit_foggy'
CLEAR_SUFFIX = '_leftImg8bit.png'
_FOGGY_NAME = re.compile(r'_leftImg8bit_foggy_beta_([0-9.]+)\.png$')


def beta_str(beta: float) -> str:
    """``0.02 -> '0.02'``, ``0.005 -> '0.005'`` (the released spelling)."""
    if beta not in FOGGY_BETAS:
        raise ValueError(f'Foggy Cityscapes beta must be one of '
                         f'{FOGGY_BETAS}, got {beta!r}')
    return repr(float(beta))


def foggy_path(clear_path: str, beta: float) -> str:
    """Path of the foggy twin of a clear ``*_leftImg8bit.png`` image.

    Works on absolute paths and on paths relative to the dataset root: the
    last ``leftImg8bit`` folder component is replaced by
    ``leftImg8bit_foggy``.
    """
    head, name = osp.split(clear_path)
    if not name.endswith(CLEAR_SUFFIX):
        raise ValueError(f'not a Cityscapes clear image name: {clear_path}')
    parts = head.split(osp.sep)
    if CLEAR_DIR not in parts:
        raise ValueError(f'no `{CLEAR_DIR}` folder in {clear_path}')
    idx = len(parts) - 1 - parts[::-1].index(CLEAR_DIR)
    parts[idx] = FOGGY_DIR
    stem = name[:-len(CLEAR_SUFFIX)]
    return osp.join(
        osp.sep.join(parts),
        f'{stem}_leftImg8bit_foggy_beta_{beta_str(beta)}.png')


def split_beta(path: str) -> Tuple[str, str]:
    """The clear twin's name of a foggy image name and its beta as written:
    ``'a/x_leftImg8bit_foggy_beta_0.02.png' -> ('a/x_leftImg8bit.png',
    '0.02')``; any other name is returned as it is, with ``'clear'``."""
    match = _FOGGY_NAME.search(path or '')
    if match is None:
        return path, 'clear'
    return path[:match.start()] + CLEAR_SUFFIX, match.group(1)
