"""tools/misc/draw_fog.py on the tiny generated tree: one row per beta,
three titled columns and the caption; a missing twin names the command
that renders it."""
import os

import cv2
import pytest
from tool_helpers import load_tool


def test_draws_a_row_per_beta(cityscapes_like_root, tmp_path, capsys):
    tool = load_tool('misc/draw_fog.py')
    out = str(tmp_path / 'fog.png')
    tool.main([cityscapes_like_root, '--betas', '0.01', '0.02', '--out',
               out])
    assert 'betas 0.01 0.02' in capsys.readouterr().out
    drawn = cv2.imread(out)
    # 12 x (2.6 * 2 + 0.6) inches at 100 dpi
    assert drawn.shape == (580, 1200, 3)
    assert len(tool.COLUMNS) == 3 and 'horizon row' in tool.CAPTION


def test_missing_twin_and_bad_betas(cityscapes_like_root, tmp_path, capsys):
    tool = load_tool('misc/draw_fog.py')
    image, twins = tool.scene(cityscapes_like_root, 'val', [0.02])
    assert twins[0].endswith('_leftImg8bit_foggy_beta_0.02.png')
    with pytest.raises(FileNotFoundError,
                       match=r'no depth-rendered fog at beta 0.03; render it '
                       r'with python tools/misc/generate_cityscapes_like.py '
                       r'.* --betas 0.03'):
        tool.scene(cityscapes_like_root, 'val', [0.03])
    empty = tmp_path / 'empty'
    os.makedirs(empty)
    with pytest.raises(FileNotFoundError, match='no val image under'):
        tool.scene(str(empty), 'val', [0.02])
    with pytest.raises(SystemExit):
        tool.parse_args([str(empty), '--betas', '0', '--out', 'x.png'])
    assert '--betas must be > 0' in capsys.readouterr().err
