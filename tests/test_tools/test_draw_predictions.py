"""Smoke test of tools/misc/draw_predictions.py: the demo model (random
weights) on one clear image and its foggy twin, one row of two panels."""
import glob
import os.path as osp

import cv2

from tool_helpers import DEMO, demo_checkpoint, load_tool


def test_clear_and_foggy_panels(cityscapes_like_root, tmp_path):
    ckpt = demo_checkpoint(str(tmp_path / 'demo.pth'))
    image = sorted(glob.glob(osp.join(
        cityscapes_like_root, 'leftImg8bit', 'val', '*', '*.png')))[0]
    out = str(tmp_path / 'pred.png')
    load_tool('misc/draw_predictions.py').main(
        [DEMO, ckpt, image, '--betas', '0.02', '--out', out])
    drawn = cv2.imread(out)
    h, w = cv2.imread(image).shape[:2]
    assert drawn.shape == (h, 2 * w, 3)  # clear | foggy, one scene
    # the two panels show different pictures (the foggy twin is hazier)
    assert not (drawn[:, :w] == drawn[:, w:]).all()
