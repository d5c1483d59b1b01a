"""Geometry of the generated scenes: clipping, joined loops, the camera,
the painter's order, the noise."""
import numpy as np
import pytest
from PIL import Image, ImageDraw
from scipy import ndimage

from cbnet_tools.synthetic.scene import (INSTANCE_CLASSES, MIN_HEIGHT_PX,
                                         SceneCamera, clip_loop, sample_scene)
from cbnet_tools.synthetic.shapes import (LOOKS, SILHOUETTES, ellipse, extent,
                                          inset, join_loops, ring)
from cbnet_tools.synthetic.texture import fade, value_noise


def _fill(poly, w=64, h=48):
    img = Image.new('L', (w, h), 0)
    ImageDraw.Draw(img).polygon([tuple(p) for p in np.asarray(
        poly, float).tolist()], fill=1)
    return np.asarray(img, bool)


@pytest.mark.parametrize('poly', [
    [(-30, -20), (100, 10), (40, 90)],                      # corners out
    [(10, 10), (200, 10), (200, 30), (30, 30), (30, 200), (10, 200)],  # L
    [(5, 5), (20, 5), (20, 20), (5, 20)],                   # inside
])
def test_clip_loop_keeps_the_image_part(poly):
    """Clipping changes no pixel inside the image (PIL clips the raw
    polygon itself: the reference)."""
    clipped = clip_loop(np.asarray(poly, float), 64, 48)
    assert clipped[:, 0].min() >= 0 and clipped[:, 0].max() <= 63
    assert clipped[:, 1].min() >= 0 and clipped[:, 1].max() <= 47
    ref, got = _fill(poly), _fill(clipped)
    assert (ref != got).sum() <= 0.01 * ref.sum() + 2


def test_clip_loop_outside_is_empty():
    assert clip_loop(np.array([(-9, -9), (-1, -9), (-5, -1)], float),
                     64, 48).shape == (0, 2)


def test_join_loops_cuts_holes():
    """A ring (outer circle + reversed inner one) joined with a disc
    fills as the XOR: the ring's area plus the disc's."""
    loops = ring(200, 200, 150, 50, n=64) + [ellipse(450, 330, 30, 30, 64)]
    img = Image.new('L', (600, 400), 0)
    ImageDraw.Draw(img).polygon([tuple(p) for p in join_loops(loops)],
                                fill=1)
    area = np.asarray(img, bool).sum()
    want = np.pi * (150**2 - 100**2) + np.pi * 30**2
    assert abs(area - want) < 0.03 * want
    assert not np.asarray(img)[200, 200]  # the hole


def test_inset_square():
    sq = np.array([(0, 0), (4, 0), (4, 4), (0, 4)], float)
    np.testing.assert_allclose(
        inset(sq, 1.0), [(1, 1), (3, 1), (3, 3), (1, 3)], atol=1e-12)


def test_silhouettes_have_no_holes():
    """Annotated outlines are one loop each (Cityscapes: no holes); only
    LOOKS paint see-through parts."""
    for key, loops in SILHOUETTES.items():
        assert len(loops) == 1, key
        x0, y0, x1, y1 = extent(loops)
        assert y0 >= -1e-9 and x1 > x0 and y1 > 0, key
    assert set(LOOKS) <= set(SILHOUETTES)


def _raster(loops, height=400, frame=None):
    """A silhouette drawn ``height`` px tall (in the box ``frame`` of
    another one, metres)."""
    x0, y0, x1, y1 = frame or extent(loops)
    s = height / (y1 - y0)
    img = Image.new('L', (int((x1 - x0) * s) + 10, height + 10), 0)
    ImageDraw.Draw(img).polygon(
        [(float((x - x0) * s + 5), float(height + 5 - (y - y0) * s))
         for x, y in join_loops(loops)], fill=1)
    return np.asarray(img, bool)


def test_thin_silhouettes():
    """Limbs, legs either side of a wheel, a handlebar over a tyre: an
    erosion by 2% of the height removes over a quarter of these
    silhouettes and under a sixth of the vehicles' bodies."""
    for key, loops in SILHOUETTES.items():
        m = _raster(loops)
        lost = 1 - ndimage.binary_erosion(m, iterations=8).sum() / m.sum()
        if key[0] in ('person', 'rider') or key in (('bicycle', 'rear'),
                                                    ('motorcycle', 'rear')):
            assert lost > 0.25, (key, lost)
        elif key[0] in ('car', 'truck', 'bus', 'train'):
            assert lost < 0.15, (key, lost)
    # a bicycle's painted tyres and tubes cover under half its outline
    frame = extent(SILHOUETTES[('bicycle', 'side')])
    look, outline = (_raster(LOOKS[('bicycle', 'side')], frame=frame),
                     _raster(SILHOUETTES[('bicycle', 'side')]))
    assert (look & outline).sum() < 0.5 * outline.sum()


def test_camera_ground_plane():
    cam = SceneCamera(128, 256)
    z = np.array([6.0, 20.0, 100.0])
    _, rows = cam.project(0.0, 0.0, z)
    np.testing.assert_allclose(cam.ground_depth()[np.floor(rows).astype(
        int)], z, rtol=0.2)


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_sample_scene(seed):
    cam = SceneCamera(128, 256)
    scene = sample_scene(cam, np.random.default_rng(seed), crowd=True)
    front = [p for p in scene if p.surface in ('object', 'flat')]
    depths = [p.depth for p in front]
    assert depths == sorted(depths, reverse=True)  # far to near
    for p in scene:
        assert p.polygon.dtype == np.int64
        assert (p.polygon >= 0).all()
        assert (p.polygon[:, 0] < 256).all() and (p.polygon[:, 1] < 128).all()
    objects = [p for p in scene if p.surface == 'object']
    assert {p.label for p in objects} >= set(INSTANCE_CLASSES)
    assert any(p.label.endswith('group') for p in objects)
    for p in objects:  # tall enough to be drawn
        assert np.ptp(p.polygon[:, 1]) >= MIN_HEIGHT_PX - 2
    empty = sample_scene(cam, np.random.default_rng(seed), empty=True)
    assert not any(p.surface == 'object' for p in empty)


def test_min_height_px():
    """No object (before clipping at the border) is shorter than asked."""
    cam = SceneCamera(128, 256)
    for seed in range(3):
        scene = sample_scene(cam, np.random.default_rng(seed),
                             min_height_px=30)
        heights = [np.ptp(p.polygon[:, 1]) for p in scene
                   if p.surface == 'object' and p.polygon[:, 1].min() > 0
                   and p.polygon[:, 1].max() < 127]
        assert heights and min(heights) >= 28, heights


def test_value_noise():
    x, y = np.meshgrid(np.linspace(0, 20, 400), np.linspace(0, 10, 200))
    n = value_noise(x, y, 3)
    assert n.min() >= -1 and n.max() <= 1 and n.std() > 0.2
    np.testing.assert_array_equal(n, value_noise(x, y, 3))
    assert np.abs(n - value_noise(x, y, 4)).mean() > 0.1
    # smooth: neighbours 0.05 cells apart differ little
    assert np.abs(np.diff(n, axis=1)).max() < 0.3
    assert fade(np.array(2.0), np.array(1.0)) == 1.0
    assert fade(np.array(0.5), np.array(1.0)) == 0.0
