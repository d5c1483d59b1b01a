import os
import subprocess
import sys

import numpy as np
import pytest
from mmcv import imwrite
from mmcv.transforms import Compose
from mmdet.registry import TRANSFORMS

import cbnet_mmdet  # noqa: F401

H, W = 120, 200


@pytest.fixture
def pair(tmp_path):
    """A clear image whose pixels encode their coordinates, and its "foggy"
    twin ``255 - clear``: any crop/flip/resize shows in the decoded box."""
    y, x = np.mgrid[:H, :W]
    clear = np.stack([x, y, np.full_like(x, 77)], -1).astype(np.uint8)
    paths = dict(img_path=str(tmp_path / 'clear.png'),
                 foggy_img_path=str(tmp_path / 'foggy.png'))
    imwrite(clear, paths['img_path'])
    imwrite(255 - clear, paths['foggy_img_path'])
    return paths


def decoded_box(img_half, foggy):
    """(x_min, y_min, x_max, y_max) of source pixels shown in a half."""
    img = 255 - img_half.astype(int) if foggy else img_half.astype(int)
    x, y = img[..., 0], img[..., 1]
    return x.min(), y.min(), x.max(), y.max(), x[0, 0], y[0, 0]


@pytest.mark.parametrize('seed', range(5))
def test_identical_crop_flip_resize(pair, seed):
    pipeline = Compose([
        dict(type='CBNetLoadPairedImageFromFile'),
        dict(type='RandomResize', scale=(260, 150), ratio_range=(0.5, 1.0),
             keep_ratio=True, interpolation='nearest'),
        dict(type='RandomCrop', crop_size=(40, 60)),
        dict(type='RandomFlip', prob=0.5, direction=['horizontal',
                                                     'vertical']),
    ])
    np.random.seed(seed)
    out = pipeline(dict(pair))
    img = out['img']
    assert img.shape[2] == 6 and img.dtype == np.uint8
    foggy, clear = img[..., :3], img[..., 3:]
    # identical geometry: every pixel of the foggy half is the twin of the
    # clear pixel at the same place
    np.testing.assert_array_equal(foggy, 255 - clear)
    assert (clear[..., 2] == 77).all()
    box = decoded_box(clear, False)
    assert decoded_box(foggy, True) == box
    assert box[2] - box[0] < W - 1  # it did crop


def test_pack_gives_six_channel_input(pair):
    pipeline = Compose([
        dict(type='CBNetLoadPairedImageFromFile'),
        dict(type='PackDetInputs', meta_keys=('img_path', 'img_shape')),
    ])
    out = pipeline(dict(pair, instances=[]))
    assert tuple(out['inputs'].shape) == (6, H, W)


def test_bad_input(pair, tmp_path):
    load = TRANSFORMS.build(dict(type='CBNetLoadPairedImageFromFile'))
    with pytest.raises(KeyError, match='foggy_img_path'):
        load(dict(img_path=pair['img_path']))
    small = str(tmp_path / 'small.png')
    imwrite(np.zeros((10, 10, 3), np.uint8), small)
    with pytest.raises(ValueError, match='differ in size'):
        load(dict(img_path=pair['img_path'], foggy_img_path=small))
    with pytest.raises(FileNotFoundError):
        load(dict(img_path=pair['img_path'],
                  foggy_img_path=str(tmp_path / 'missing.png')))
    with pytest.raises(ValueError, match='color_type'):
        TRANSFORMS.build(dict(type='CBNetLoadPairedImageFromFile',
                              color_type='grayscale'))


@pytest.mark.parametrize('damage', ['empty', 'truncated'])
@pytest.mark.parametrize('which', ['foggy_img_path', 'img_path'])
def test_damaged_twin_is_a_clear_error_naming_it(pair, damage, which):
    path = pair[which]
    with open(path, 'rb') as f:
        data = f.read()
    with open(path, 'wb') as f:
        f.write(b'' if damage == 'empty' else data[:len(data) // 3])
    load = TRANSFORMS.build(dict(type='CBNetLoadPairedImageFromFile'))
    with pytest.raises(ValueError) as err:
        load(dict(pair))
    assert str(err.value).startswith(f'cannot decode image {path}')


@pytest.mark.slow  # a fresh -O process compiles .opt-1.pyc: ~30 s once
def test_truncated_twin_is_a_clear_error_under_python_O(pair):
    """MMCV's `assert img is not None` is stripped by -O: still our
    error (run in a subprocess with -O)."""
    with open(pair['foggy_img_path'], 'rb') as f:
        data = f.read()
    with open(pair['foggy_img_path'], 'wb') as f:
        f.write(data[:len(data) // 3])
    code = (
        'import cbnet_mmdet\n'
        'from mmdet.registry import TRANSFORMS\n'
        "load = TRANSFORMS.build(dict(type='CBNetLoadPairedImageFromFile'))\n"
        f'load({dict(pair)!r})\n')
    proc = subprocess.run([sys.executable, '-O', '-c', code],
                          capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, OMP_NUM_THREADS='1'))
    assert proc.returncode != 0
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith('ValueError: cannot decode image '
                           f"{pair['foggy_img_path']}"), proc.stderr
