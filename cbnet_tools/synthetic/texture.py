"""Colouring of rasterised street scenes: procedural textures and shading.

Every surface is textured in its own metric coordinates, so texture shrinks
with distance as in a photograph: the road and sidewalks in ground
coordinates ``(X, Z)`` (asphalt grain and patches, dashed centre line and
solid edge lines, paving tiles, curbs), facades in ``(Z, Y)`` and
camera-facing stuff in ``(X, Y)`` (plaster, window grids by floor, shop
fronts; leaves), objects in their own frame (paint, glass with a sky
reflection, tyres and hubs, lights and plates, clothes and skin). Objects
are lit from above (brighter top, cylindrical shading of bodies) and cast a
contact shadow on the road. Detail finer than a pixel fades to its mean
(each noise octave and painted line is weighted by its size over the
pixel's footprint), so far surfaces do not alias into salt noise.

The noise is value noise on an integer lattice hashed with integer
arithmetic only (vectorised numpy, no trigonometric hash), so a seed gives
byte-identical images on any machine.
"""
from typing import Dict, Sequence

import numpy as np

from .scene import CAMERA_HEIGHT, INSTANCE_CLASSES, SceneCamera, ScenePolygon
from .shapes import BICYCLE_WHEELS, MOTORCYCLE_WHEELS

#: Linear ramp (pixels of footprint per detail size) over which a detail
#: fades out: full contrast at >= 2 px, none at <= 0.5 px.
FADE_PX = (0.5, 2.0)
_M32 = np.uint64(0xFFFFFFFF)


def _hash(ix: np.ndarray, iy: np.ndarray, seed: int) -> np.ndarray:
    """Uniform [0, 1) per integer lattice point (a 32-bit integer mix)."""
    h = (ix.astype(np.int64).astype(np.uint64) * np.uint64(374761393)
         + iy.astype(np.int64).astype(np.uint64) * np.uint64(668265263)
         + np.uint64(seed) * np.uint64(2246822519)) & _M32
    h = ((h ^ (h >> np.uint64(13))) * np.uint64(1274126177)) & _M32
    h = h ^ (h >> np.uint64(16))
    return h.astype(np.float64) / 2.0**32


def value_noise(x: np.ndarray, y: np.ndarray, seed: int) -> np.ndarray:
    """Smooth value noise in [-1, 1], one lattice cell per unit."""
    ix, iy = np.floor(x), np.floor(y)
    fx, fy = x - ix, y - iy
    fx, fy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)
    a, b = _hash(ix, iy, seed), _hash(ix + 1, iy, seed)
    c, d = _hash(ix, iy + 1, seed), _hash(ix + 1, iy + 1, seed)
    top, bottom = a + (b - a) * fx, c + (d - c) * fx
    return 2 * (top + (bottom - top) * fy) - 1


def fade(size: np.ndarray, footprint: np.ndarray) -> np.ndarray:
    """Contrast weight of a detail of ``size`` seen with ``footprint``
    (same unit per pixel): 1 when it spans >= 2 px, 0 at <= 0.5 px."""
    lo, hi = FADE_PX
    return np.clip((size / footprint - lo) / (hi - lo), 0.0, 1.0)


def fbm(x: np.ndarray, y: np.ndarray, cell: float, footprint: np.ndarray,
        seed: int, octaves: int = 3) -> np.ndarray:
    """Fractal noise about [-1, 1]: ``octaves`` value noises of cell
    ``cell, cell / 2, ...`` (units of ``x``), halving amplitude, each faded
    by :func:`fade` of its cell over ``footprint``."""
    out = np.zeros(np.shape(x))
    amp, norm = 1.0, 0.0
    for k in range(octaves):
        c = cell / 2**k
        out += amp * fade(c, footprint) * value_noise(x / c, y / c,
                                                      seed + 7919 * k)
        norm += amp
        amp /= 2
    return out / norm


def _line(dist: np.ndarray, width: float, footprint: np.ndarray
          ) -> np.ndarray:
    """Coverage in [0, 1] of a painted line of ``width`` at ``dist`` from
    its axis: its area share of the pixel once thinner than a pixel."""
    half = np.maximum(width, footprint) / 2
    return (np.abs(dist) < half) * np.minimum(1.0, width / footprint)


def _mix(a: np.ndarray, b, w: np.ndarray) -> np.ndarray:
    """``a (1 - w) + b w`` with ``w`` per pixel, RGB last."""
    return a + (np.asarray(b, np.float64) - a) * w[..., None]


class _Pixels:
    """Coordinates of the pixels of one group of polygons."""

    def __init__(self, sel: np.ndarray, order: np.ndarray, depth: np.ndarray,
                 cam: SceneCamera, scene: Sequence[ScenePolygon]):
        self.rows, self.cols = np.nonzero(sel)
        self.idx = order[sel]
        self.depth = depth[sel]
        r = self.rows + 0.5 - cam.horizon
        c = self.cols + 0.5 - cam.cx
        self.foot = self.depth / cam.focal  # metres per pixel
        self.x = c * self.foot                       # world X
        self.y = CAMERA_HEIGHT - r * self.foot       # world Y
        ox, oy, sx, sy = (np.array(v, np.float64)[self.idx] for v in zip(
            *[(*p.origin, *p.scale) for p in scene]))
        self.lx = (self.cols + 0.5 - ox) / sx  # the polygon's own metres
        self.ly = (oy - self.rows - 0.5) / sy
        self.lfoot = 1.0 / np.abs(sy)
        cols = np.zeros((len(scene), 3, 3))
        for i, p in enumerate(scene):
            for k, c3 in enumerate(p.colours[:3]):
                cols[i, k] = c3
        self.colours = cols[self.idx]  # [N, 3, 3]


def _sky(px: _Pixels, cam: SceneCamera, seed: int) -> np.ndarray:
    t = np.clip(px.rows / max(cam.horizon, 1.0), 0, 1)[:, None]
    rgb = np.array([110., 150., 210.]) * (1 - t) + np.array(
        [200., 212., 228.]) * t
    cloud = fbm(px.cols / cam.width * 6, px.rows / cam.width * 12, 1.0,
                np.full(len(t), 1e-3), seed, octaves=4)
    return _mix(rgb, (235, 238, 242), np.clip(cloud * 1.8 - 0.2, 0, 0.8))


def _road(px: _Pixels, scene, seed: int) -> np.ndarray:
    z, x, f = px.depth, px.x, px.foot
    grey = 92 + 12 * fbm(x, z, 4.0, f, seed, 2) + 10 * fbm(
        x, z, 0.4, f, seed + 1, 2)
    rgb = np.stack([grey, grey, grey * 1.04], 1)
    marks = np.zeros(len(z))
    for i in np.unique(px.idx):
        sel = px.idx == i
        for k, mx in enumerate(scene[i].marks):
            cover = _line(x[sel] - mx, 0.15, f[sel])
            if k == 0:  # dashed: 3 m of paint every 9 m
                cover = cover * (np.mod(z[sel], 9.0) < 3.0)
            marks[sel] = np.maximum(marks[sel], cover)
    return _mix(rgb, (215, 215, 210), 0.9 * marks)


def _sidewalk(px: _Pixels, seed: int) -> np.ndarray:
    z, x, f = px.depth, px.x, px.foot
    grout = np.maximum(_line(np.mod(x + 0.25, 0.5) - 0.25, 0.03, f),
                       _line(np.mod(z + 0.25, 0.5) - 0.25, 0.03, f))
    v = 168 + 10 * fbm(x, z, 2.0, f, seed, 3) - 35 * grout
    return np.stack([v, v * 0.97, v * 0.93], 1)


def _building(px: _Pixels, along: np.ndarray, up: np.ndarray,
              foot: np.ndarray, light: np.ndarray, seed: int) -> np.ndarray:
    """Plaster with a window grid per 3.2 m floor, shop fronts below."""
    wall = px.colours[:, 0] * (1 + 0.08 * fbm(along, up, 3.0, foot, seed,
                                              3))[:, None]
    floor_y = np.mod(up, 3.2)
    upper = (up > 3.2) & (floor_y > 0.9) & (floor_y < 2.3) & (
        np.mod(along, 2.6) < 1.3)
    shop = (up > 0.4) & (up < 2.7) & (np.mod(along, 5.0) < 3.5)
    glass = np.array([45., 55., 70.]) + 25 * (
        1 + value_noise(along / 3, up / 3, seed + 5))[:, None]
    w = (upper | shop) * fade(1.3, foot)
    # sub-pixel windows: the wall darkens by their area share (~20%)
    rgb = _mix(wall, np.array([60., 68., 80.]), 0.2 * (1 - fade(1.3, foot)))
    rgb = rgb + (glass - rgb) * w[:, None]
    return rgb * light[:, None]


def _leaves(along, up, foot, seed) -> np.ndarray:
    n = fbm(along, up, 1.2, foot, seed, 3)
    rgb = _mix(np.full((len(n), 3), (55., 85., 35.)), (120, 150, 70),
               np.clip(n * 0.8 + 0.5, 0, 1))
    return _mix(rgb, (25, 38, 18), np.clip(-n * 2.5 - 0.6, 0, 0.9))


def _stuff(px: _Pixels, scene, seed) -> np.ndarray:
    """Buildings, vegetation, poles and signs (facade or flat)."""
    facade = np.array([p.surface == 'facade' for p in scene])[px.idx]
    plane = np.array([p.plane_x for p in scene])[px.idx]
    along = np.where(facade, px.depth, px.x)
    # facades: their height from the row; flat stuff: its own frame
    up = np.where(facade, px.y, px.ly)
    light = np.where(facade & (plane > 0), 0.8, 1.0)  # sun from the left
    label = np.array([p.label for p in scene])[px.idx]
    has_col = px.colours[:, 0].sum(1) > 0
    rgb = np.zeros((len(px.idx), 3))
    sel = label == 'building'
    rgb[sel] = _building(_sub(px, sel), along[sel], up[sel], px.foot[sel],
                         light[sel], seed)
    sel = (label == 'vegetation') & ~has_col
    rgb[sel] = _leaves(along[sel], up[sel], px.foot[sel], seed + 11)
    sel = (label == 'vegetation') & has_col  # tree trunks: bark
    rgb[sel] = px.colours[sel, 0] * (1 + 0.2 * fbm(
        px.lx[sel], up[sel], 0.3, px.foot[sel], seed + 13, 2))[:, None]
    sel = label == 'pole'  # a metal cylinder, 0.16 m
    u = np.clip(px.lx[sel] / 0.16, 0, 1)
    rgb[sel] = np.array([128., 130., 135.]) * (
        0.55 + 0.55 * np.sin(np.pi * u))[:, None]
    sel = label == 'traffic sign'  # a blue plate with a white border
    core = ((np.abs(px.lx[sel] - 0.3) < 0.24)
            & (np.abs(px.ly[sel] - 2.5) < 0.24))
    rgb[sel] = np.where(core[:, None], (30., 80., 170.), (225., 225., 225.))
    return rgb


def _sub(px: _Pixels, sel: np.ndarray) -> _Pixels:
    """The pixels ``sel`` of a group."""
    out = object.__new__(_Pixels)
    for k, v in vars(px).items():
        setattr(out, k, v[sel])
    return out


def _in_wheels(lx, ly, centres, r, width) -> np.ndarray:
    """Pixels on the tyres (rings) of wheels at ``centres`` (x), radius r.
    """
    d = np.min([np.hypot(lx - c, ly - r) for c in centres], 0)
    return (d > r - width - 0.01) & (d < r + 0.02)


def _glass(ly, lo, hi) -> np.ndarray:
    """Window glass: dark, reflecting the sky more towards the top."""
    t = np.clip((ly - lo) / max(hi - lo, 1e-6), 0, 1)
    return np.stack([35 + 90 * t, 45 + 100 * t, 60 + 120 * t], 1)


def _object_rgb(px: _Pixels, cls: str, side: np.ndarray, seed: int
                ) -> np.ndarray:
    """Paint, glass, tyres, lights, clothes of the pixels of one class."""
    lx, ly = px.lx, px.ly
    paint, second, third = (px.colours[:, k] for k in range(3))
    rgb = paint.copy()
    dark = np.array([28., 28., 30.])
    if cls in ('person', 'rider'):
        legs = ly < (0.95 if cls == 'rider' else 0.85)
        rgb[legs] = second[legs]
        headp = ly > 1.5
        rgb[headp] = third[headp]
        if cls == 'rider':  # a helmet
            top = ly > 1.66
            rgb[top] = paint[top] * 0.6
        centre = 0.3 if cls == 'rider' else 0.25
        u = np.clip((lx - centre) / 0.3, -1, 1)
        rgb *= (1 - 0.3 * u**2)[:, None]
    elif cls == 'car':
        win = np.where(side, (lx > 1.45) & (lx < 2.95)
                       & (np.abs(lx - 2.2) > 0.05),
                       (lx > 0.4) & (lx < 1.4)) & (ly > 0.95) & (ly < 1.38)
        rgb[win] = _glass(ly[win], 0.95, 1.38)
        tyre = np.where(side, _in_wheels(lx, ly, (0.75, 3.45), 0.32, 0.32),
                        ly < 0.12)
        rgb[tyre] = dark
        light = ~side & (ly > 0.72) & (ly < 0.88) & ((lx < 0.3) | (lx > 1.5))
        rgb[light] = (185., 25., 25.)
        plate = ~side & (ly > 0.38) & (ly < 0.52) & (np.abs(lx - 0.9) < 0.26)
        rgb[plate] = (230., 230., 225.)
        sill = (ly > 0.12) & (ly < 0.3) & ~tyre
        rgb[sill] *= 0.55
    elif cls in ('truck', 'bus', 'train'):
        wheels, r = dict(truck=((1.2, 2.3, 6.5), 0.5),
                         bus=((2.5, 9.5), 0.5),
                         train=((3.0, 5.0, 20.0, 22.0), 0.4))[cls]
        if cls == 'truck':  # ribbed box, glass in the cab
            win = side & (lx > 6.7) & (ly > 1.9) & (ly < 2.8)
            rib = (side & (lx < 5.5)) | (~side & (ly > 0.6))
            ribs = np.sign(np.sin(2 * np.pi * lx[rib] / 0.5))  # 0.5 m
            rgb[rib] *= (1 + 0.06 * ribs)[:, None]
            lo, hi = 1.9, 2.8
        elif cls == 'bus':  # a band of windows between pillars
            win = (ly > 1.5) & (ly < 2.7) & np.where(
                side, np.mod(lx, 1.3) > 0.15, np.abs(lx - 1.27) < 0.95)
            lo, hi = 1.5, 2.7
        else:  # tram: a stripe, windows, the pantograph
            stripe = (ly > 0.9) & (ly < 1.2)
            rgb[stripe] *= 0.35
            win = (ly > 1.6) & (ly < 2.8) & np.where(
                side, np.mod(lx, 1.8) > 0.25, np.abs(lx - 1.32) < 1.0)
            panto = ly > 3.5
            rgb[panto] = (70., 70., 75.)
            lo, hi = 1.6, 2.8
        rgb[win] = _glass(ly[win], lo, hi)
        tyre = np.where(side, _in_wheels(lx, ly, wheels, r, r), ly < r)
        rgb[tyre] = dark
    elif cls == 'bicycle':
        (xr, xf), r, w = BICYCLE_WHEELS
        tyre = np.where(side, _in_wheels(lx, ly, (xr, xf), r, w), ly < 0.7)
        rgb[tyre] = dark
    elif cls == 'motorcycle':
        (xr, xf), r, w = MOTORCYCLE_WHEELS
        tyre = np.where(side, _in_wheels(lx, ly, (xr, xf), r, w), ly < 0.35)
        rgb[tyre] = dark
        engine = side & (lx > 0.72) & (lx < 1.28) & (ly < 0.68)
        rgb[engine] = (115., 115., 118.)
    # lit from above, slightly uneven paint
    top = np.clip(ly / 1.8, 0, 1.5)
    grain = fbm(lx, ly, 0.5, px.lfoot, seed, 2)
    return rgb * (0.75 + 0.2 * top + 0.06 * grain)[:, None]


def _shadows(rgb: np.ndarray, ground: np.ndarray,
             scene: Sequence[ScenePolygon]) -> None:
    """Darken the road under each object: a soft ellipse at its foot."""
    h, w = ground.shape
    for p in scene:
        if p.surface != 'object':
            continue
        x0, x1 = p.polygon[:, 0].min(), p.polygon[:, 0].max()
        (_, oy), (_, sy) = p.origin, p.scale
        cx, rx = (x0 + x1) / 2, max((x1 - x0) / 2 * 1.1, 1.0)
        ry = max(0.25 * sy, 1.0)
        r0, r1 = int(max(oy - ry, 0)), int(min(oy + ry + 1, h))
        c0, c1 = int(max(cx - rx, 0)), int(min(cx + rx + 1, w))
        if r0 >= r1 or c0 >= c1:
            continue
        yy, xx = np.mgrid[r0:r1, c0:c1] + 0.5
        d = ((xx - cx) / rx)**2 + ((yy - oy) / ry)**2
        dim = 1 - 0.45 * np.clip(1.2 - d, 0, 1) * ground[r0:r1, c0:c1]
        rgb[r0:r1, c0:c1] *= dim[..., None]


def render_rgb(order: np.ndarray, scene: Sequence[ScenePolygon],
               cam: SceneCamera, depth: np.ndarray,
               rng: np.random.Generator) -> np.ndarray:
    """Colour a rasterised scene.

    Args:
        order (np.ndarray): ``int32[H, W]`` index of the polygon covering
            each pixel (painter's order, last drawn wins).
        scene (Sequence[ScenePolygon]): The scene polygons.
        cam (SceneCamera): Its camera.
        depth (np.ndarray): ``float64[H, W]`` depth, metres
            (:func:`~.scene.pixel_depth`).
        rng (np.random.Generator): Source of randomness (noise seed,
            exposure, sensor noise).

    Returns:
        np.ndarray: ``uint8[H, W, 3]`` RGB image.
    """
    seed = int(rng.integers(2**31))
    labels = np.array([p.label for p in scene])
    surface = np.array([p.surface for p in scene])
    base = np.array([lab[:-5] if lab.endswith('group') else lab
                     for lab in labels])
    rgb = np.zeros(order.shape + (3, ))
    groups: Dict[str, np.ndarray] = {
        'sky': surface == 'sky',
        'road': labels == 'road',
        'sidewalk': labels == 'sidewalk',
        'stuff': np.isin(surface, ['facade', 'flat']),
    }
    for cls in INSTANCE_CLASSES:
        groups[cls] = (surface == 'object') & (base == cls)
    for name, members in groups.items():
        sel = members[order]
        if not sel.any():
            continue
        px = _Pixels(sel, order, depth, cam, scene)
        if name == 'sky':
            out = _sky(px, cam, seed)
        elif name == 'road':
            out = _road(px, scene, seed + 1)
        elif name == 'sidewalk':
            out = _sidewalk(px, seed + 2)
        elif name == 'stuff':
            out = _stuff(px, scene, seed + 3)
        else:
            side = np.array([p.view == 'side' for p in scene])[px.idx]
            out = _object_rgb(px, name, side, seed + 4)
        rgb[sel] = out
    _shadows(rgb, (surface == 'ground')[order], scene)
    gain = rng.uniform(0.85, 1.1) * rng.uniform(0.97, 1.03, size=3)
    rgb = rgb * gain + rng.normal(0, 2.5, size=rgb.shape)
    return np.clip(np.rint(rgb), 0, 255).astype(np.uint8)
