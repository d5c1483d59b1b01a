"""Smoke test of tools/misc/draw_predictions.py: the demo model (random
weights) on one clear image and its foggy twin, one row of two panels."""
import glob
import os.path as osp

import cv2
import numpy as np
import pytest
from mmengine.config import Config

from tool_helpers import DEMO, demo_checkpoint, load_tool


def test_clear_and_foggy_panels(cityscapes_like_root, tmp_path, capsys):
    ckpt = demo_checkpoint(str(tmp_path / 'demo.pth'))
    image = sorted(glob.glob(osp.join(
        cityscapes_like_root, 'leftImg8bit', 'val', '*', '*.png')))[0]
    out = str(tmp_path / 'pred.png')
    load_tool('misc/draw_predictions.py').main(
        [DEMO, ckpt, image, '--betas', '0.02', '--out', out])
    thr, _ = load_tool('misc/draw_predictions.py').evaluation_score_thr(
        Config.fromfile(DEMO))
    assert f'drawing predictions scoring >= {thr} (the score_thr of its ' \
        'CBNetInstanceMIoUMetric)' in capsys.readouterr().out
    drawn = cv2.imread(out)
    h, w = cv2.imread(image).shape[:2]
    tool = load_tool('misc/draw_predictions.py')
    top = tool.TITLE_HEIGHT
    # clear | foggy, one scene, each under its title band
    assert drawn.shape == (top + h, 2 * w, 3)
    # the two panels show different pictures (the foggy twin is hazier)
    assert not (drawn[top:, :w] == drawn[top:, w:]).all()
    # titled in words: each band is the tool's own rendering of its title
    for i, title in enumerate(('clear', 'beta 0.02')):
        band = drawn[:top, i * w:(i + 1) * w]
        want = tool.titled(np.zeros((1, w, 3), np.uint8),
                           f'{title}, scores >= {thr:g}')[:top, :, ::-1]
        assert (band == want).all(), title
        assert (band < 128).any() and (band == 255).any()  # text on white


def test_threshold_is_the_evaluations(capsys):
    """Drawn from the score the config's mIoU evaluation paints masks from
    (not MMDet's 0.3, where a short-trained demo model shows nothing), as
    docs/get_started.md says."""
    tool = load_tool('misc/draw_predictions.py')
    cfg = Config.fromfile(DEMO)
    (miou, ) = [e for e in cfg.test_evaluator
                if e['type'] == 'CBNetInstanceMIoUMetric']
    thr, source = tool.evaluation_score_thr(cfg)
    assert thr == miou['score_thr'] and 'CBNetInstanceMIoUMetric' in source
    assert tool.parse_args([DEMO, 'c.pth', 'i.png', '--out',
                            'o.png']).score_thr is None
    with open(osp.join(osp.dirname(DEMO), '..', '..', 'docs',
                       'get_started.md')) as f:
        guide = ' '.join(f.read().split())
    assert f'(clear | beta 0.01 | beta 0.02) from score {thr},' in guide
    # a config without the metric: MMDet's default, said so
    assert tool.evaluation_score_thr(Config(dict(test_evaluator=dict(
        type='CocoMetric')))) == (0.3, "MMDetection's default")


def test_a_folder_is_its_images(tmp_path):
    tool = load_tool('misc/draw_predictions.py')
    (tmp_path / 'imgs').mkdir()
    for name in ('b.jpg', 'a.PNG', 'notes.txt'):
        (tmp_path / 'imgs' / name).write_bytes(b'x')
    assert tool.image_files([str(tmp_path / 'imgs')]) == [
        str(tmp_path / 'imgs' / 'a.PNG'), str(tmp_path / 'imgs' / 'b.jpg')]
    (tmp_path / 'txt').mkdir()
    (tmp_path / 'txt' / 'a.txt').write_text('x')
    with pytest.raises(ValueError, match='is a folder with no image file'):
        tool.image_files([str(tmp_path / 'txt')])
    with pytest.raises(FileNotFoundError, match='no such image or folder'):
        tool.image_files([str(tmp_path / 'none.png')])


def test_unreadable_images_are_refused_naming_the_file(tmp_path):
    tool = load_tool('misc/draw_predictions.py')
    text = tmp_path / 'notes.txt'
    text.write_text('not an image')
    good = tmp_path / 'ok.jpg'
    cv2.imwrite(str(good), np.full((32, 48, 3), 128, np.uint8))
    truncated = tmp_path / 'cut.jpg'
    truncated.write_bytes(good.read_bytes()[:40])
    for bad in (text, truncated):
        with pytest.raises(ValueError, match=f'{bad}: not a readable image'):
            # refused before any model is built (the config is not read)
            tool.main(['no_config.py', 'no.pth', str(bad), '--out',
                       str(tmp_path / 'o.png')])
    assert tool.read_image(str(good)).shape == (32, 48, 3)


@pytest.mark.parametrize('extra,message', [
    (['--score-thr', '1.5'], '--score-thr must be in'),
    (['--betas', '0'], '--betas must be > 0'),
    (['--out', 'o.txt'], 'give an image file name'),
])
def test_usage_errors_are_argparse_errors(extra, message, capsys):
    tool = load_tool('misc/draw_predictions.py')
    argv = ['c.py', 'c.pth', 'i.png', '--out', 'o.png'] + extra
    with pytest.raises(SystemExit) as err:
        tool.parse_args(argv)
    assert err.value.code == 2 and message in capsys.readouterr().err
