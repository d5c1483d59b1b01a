"""Random street scenes for the Cityscapes-like stand-in dataset.

A scene is laid out in metres around a pinhole camera :data:`CAMERA_HEIGHT`
above a flat road, looking down the street (``X`` right, ``Y`` up, ``Z``
forward): a road between two sidewalks, building and hedge facades along
both sides (planes ``X = const``), a building row closing the street far
away, poles, signs and trees on the sidewalks, and the objects: rows of
parked cars along the curbs, traffic in the lanes, pedestrians (some in
groups), cyclists and motorcyclists (a ``rider`` instance on a ``bicycle`` /
``motorcycle`` instance, as Cityscapes annotates them), parked bicycles.
Everything is projected, ``col = cx + f X / Z``, ``row = horizon +
f (CAMERA_HEIGHT - Y) / Z``, so far objects are small and near the
vanishing point; most objects are far, so most instances are small.

The scene is a list of :class:`ScenePolygon` in Cityscapes'
``*_gtFine_polygons.json`` order (drawn first = furthest back); objects are
sorted far to near, so a nearer object hides what is behind it and the
instance image keeps each instance's visible part. Nothing here draws
pixels: :mod:`.cityscapes_like` rasterises scenes with cityscapesscripts'
renderers and :mod:`.texture` colours them.
"""
import functools
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple

import numpy as np
from cityscapesscripts.helpers.labels import labels

from .shapes import LOOKS, SILHOUETTES, extent, group_loops, join_loops

#: The 8 Cityscapes instance classes evaluated by the benchmark, in label-id
#: order (person, rider, car, truck, bus, train, motorcycle, bicycle).
INSTANCE_CLASSES: Tuple[str, ...] = tuple(
    lab.name for lab in labels if lab.hasInstances and not lab.ignoreInEval)

#: Camera height above the road, metres (Cityscapes' is about 1.2 m).
CAMERA_HEIGHT = 1.3
#: Focal length as a fraction of the image width (Cityscapes: 2262 px at
#: 2048 px, a 48 deg horizontal field of view).
FOCAL_PER_WIDTH = 1.1
#: Horizon row as a fraction of the image height.
HORIZON = 0.45
#: Depth of the sky, metres; also the far clamp of the road plane. Fits the
#: 16-bit centimetre depth PNG (max 655.35 m).
SKY_DEPTH = 600.0
#: Depth range of objects, metres. The near end keeps a standing object's
#: foot inside the image (row <= height needs Z >= f h / (H - horizon),
#: 5.2 m); at the far end a person is 28 px tall at 1024x2048, 3.5 px at
#: 128x256 (not drawn there, see MIN_HEIGHT_PX).
MIN_DEPTH, MAX_DEPTH = 5.5, 140.0
#: Default smallest object height drawn, pixels. At 128x256 it keeps cars
#: nearer than 53 m and persons nearer than 62 m (objects a few pixels tall
#: are noise to a detector trained for minutes at that size); at 1024x2048
#: it drops nothing nearer than MAX_DEPTH.
MIN_HEIGHT_PX = 8.0
#: Classes that appear as crowd ("group") regions, as in Cityscapes.
GROUP_CLASSES = ('person', 'car', 'bicycle')
#: Mean number of objects of each kind per image at ``density=1``, chosen
#: to approach Cityscapes' mix (about 9 cars, 6 persons, 1 bicycle, under
#: 1 rider per fine train image; see docs/dataset.md). Many are hidden
#: (parked rows, groups) or off the image, so fewer are annotated.
MEAN_COUNTS = dict(traffic=2.5, pedestrians=14.0, cyclists=1.0,
                   parked_bicycles=0.8)

#: Colour palettes, RGB.
CAR_PAINT = ((235, 235, 232), (190, 192, 195), (120, 122, 126), (30, 32, 35),
             (40, 60, 120), (150, 30, 30), (40, 80, 55), (200, 185, 150))
TRUCK_PAINT = ((235, 235, 230), (180, 40, 35), (40, 75, 150), (220, 180, 40),
               (90, 95, 100))
BUS_PAINT = ((230, 230, 225), (230, 190, 40), (190, 40, 40), (40, 90, 160))
TRAIN_PAINT = ((235, 235, 235), (200, 40, 40), (240, 200, 40))
CLOTHES = ((30, 30, 35), (60, 70, 110), (140, 30, 35), (200, 200, 195),
           (90, 110, 60), (150, 120, 90), (70, 70, 75), (30, 60, 130),
           (220, 150, 40), (110, 40, 110))
TROUSERS = ((30, 30, 35), (40, 50, 90), (80, 80, 85), (110, 95, 70))
SKIN = ((225, 190, 165), (190, 145, 110), (140, 100, 70), (90, 65, 45))
BUILDING_PAINT = ((200, 190, 170), (160, 150, 140), (150, 80, 60),
                  (225, 220, 205), (120, 115, 110), (205, 180, 130))


@dataclass
class SceneCamera:
    """Pinhole camera of the scenes of one image size.

    Attributes:
        height (int): Image height, pixels.
        width (int): Image width, pixels.
        focal (float): Focal length, pixels.
        horizon (float): Horizon row, pixels.
        cx (float): Principal column, pixels.
    """
    height: int
    width: int
    focal: float = field(init=False)
    horizon: float = field(init=False)
    cx: float = field(init=False)

    def __post_init__(self):
        self.focal = FOCAL_PER_WIDTH * self.width
        self.horizon = HORIZON * self.height
        self.cx = self.width / 2

    def project(self, x, y, z) -> Tuple[np.ndarray, np.ndarray]:
        """Pixel ``(col, row)`` of world points, metres (``z > 0``)."""
        z = np.asarray(z, float)
        return (self.cx + self.focal * np.asarray(x, float) / z,
                self.horizon + self.focal * (CAMERA_HEIGHT -
                                             np.asarray(y, float)) / z)

    def ground_depth(self) -> np.ndarray:
        """Depth of the road plane at each row's centre, ``float64[H]``,
        metres; rows at or above the horizon get :data:`SKY_DEPTH`."""
        rows = np.arange(self.height) + 0.5 - self.horizon
        with np.errstate(divide='ignore'):
            depth = self.focal * CAMERA_HEIGHT / rows
        return np.where(rows > 0, np.minimum(depth, SKY_DEPTH), SKY_DEPTH)


@dataclass
class ScenePolygon:
    """One polygon of a scene.

    Attributes:
        label (str): Cityscapes label name (``'car'``, ``'cargroup'``,
            ``'road'``...).
        polygon (np.ndarray): Integer vertices, ``int64[K, 2]`` (x, y) in
            pixels, inside the image.
        depth (float): Distance along the optical axis, metres, of the
            whole polygon (``nan`` for the road, sidewalk and facades,
            whose depth varies per pixel).
        surface (str): How depth and texture coordinates follow the
            pixels: ``'sky'``, ``'ground'`` (the road plane),
            ``'facade'`` (the plane ``X = plane_x``), ``'flat'`` (facing
            the camera at ``depth``) or ``'object'``.
        plane_x (float): ``X`` of a facade, metres (``nan`` otherwise).
        origin (tuple): Pixel ``(col, row)`` of the polygon's own metre
            frame origin (an object's left end on the road).
        scale (tuple): Pixels per metre ``(sx, sy)`` of that frame;
            ``sx < 0`` mirrors it.
        view (str): Object view, ``'side'`` or ``'rear'`` ('' for stuff).
        colours (tuple): Up to 3 RGB colours (paint, clothes, skin...).
        marks (tuple): ``X`` of the road's painted lines, metres: the first
            dashed (the centre line), the others solid.
        look (np.ndarray, optional): Polygon of what is painted, when it
            differs from the annotated ``polygon`` (a bicycle's see-through
            wheels and frame, :data:`~.shapes.LOOKS`).
    """
    label: str
    polygon: np.ndarray
    depth: float
    surface: str
    plane_x: float = float('nan')
    origin: Tuple[float, float] = (0.0, 0.0)
    scale: Tuple[float, float] = (1.0, 1.0)
    view: str = ''
    colours: Tuple[Tuple[int, int, int], ...] = ()
    marks: Tuple[float, ...] = ()
    look: Optional[np.ndarray] = None


def pixel_depth(order: np.ndarray, scene: Sequence[ScenePolygon],
                cam: SceneCamera) -> np.ndarray:
    """Depth of each pixel of a rasterised scene, ``float64[H, W]``,
    metres (at most :data:`SKY_DEPTH`).

    Args:
        order (np.ndarray): ``int32[H, W]`` index of the polygon covering
            each pixel.
        scene (Sequence[ScenePolygon]): The scene polygons.
        cam (SceneCamera): Its camera.
    """
    surface = np.array([p.surface for p in scene])[order]
    depth = np.array([p.depth for p in scene])[order]
    ground = np.broadcast_to(cam.ground_depth()[:, None], order.shape)
    depth = np.where(surface == 'ground', ground, depth)
    plane = np.array([p.plane_x for p in scene])[order]
    cols = np.arange(cam.width) + 0.5 - cam.cx
    with np.errstate(divide='ignore', invalid='ignore'):
        facade = cam.focal * plane / cols[None, :]
    facade = np.where(facade > 0, facade, SKY_DEPTH)  # wrong side: far
    depth = np.where(surface == 'facade', facade, depth)
    return np.minimum(depth, SKY_DEPTH)


def clip_loop(poly: np.ndarray, width: int, height: int) -> np.ndarray:
    """Sutherland-Hodgman clip of a polygon to the image, ``float[K, 2]``
    pixels -> ``float[M, 2]`` (``M = 0`` when outside)."""
    lo, hi = poly.min(0), poly.max(0)
    if lo[0] >= 0 and lo[1] >= 0 and hi[0] <= width - 1 and \
            hi[1] <= height - 1:
        return np.asarray(poly, float)  # inside: nothing to clip
    if hi[0] < 0 or hi[1] < 0 or lo[0] > width - 1 or lo[1] > height - 1:
        return np.zeros((0, 2))  # wholly on one side
    pts = [tuple(p) for p in poly]
    for axis, bound, keep_low in ((0, 0, False), (0, width - 1, True),
                                  (1, 0, False), (1, height - 1, True)):
        inside = (lambda p: p[axis] <= bound) if keep_low else (
            lambda p: p[axis] >= bound)
        out = []
        for i, cur in enumerate(pts):
            prev = pts[i - 1]
            if inside(cur) != inside(prev):
                t = (bound - prev[axis]) / (cur[axis] - prev[axis])
                out.append(tuple(a + t * (b - a) for a, b in zip(prev, cur)))
            if inside(cur):
                out.append(cur)
        pts = out
        if not pts:
            break
    return np.asarray(pts, float).reshape(-1, 2)


def _polygon(loops: Sequence[np.ndarray], cam: SceneCamera
             ) -> Optional[np.ndarray]:
    """Clip pixel loops to the image, join them, round to integers."""
    kept = [c for c in (clip_loop(lp, cam.width, cam.height) for lp in loops)
            if len(c) >= 3]
    if not kept:
        return None
    return np.rint(join_loops(kept)).astype(np.int64)


def _flat(label: str, x0: float, x1: float, y0: float, y1: float,
          z: float, cam: SceneCamera, loop: Optional[np.ndarray] = None,
          colours: tuple = ()) -> Optional[ScenePolygon]:
    """A camera-facing stuff polygon at depth ``z``: the rectangle
    ``[x0, x1] x [y0, y1]`` (metres) or ``loop`` (world ``X, Y``)."""
    if loop is None:
        loop = np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], float)
    col, row = cam.project(loop[:, 0], loop[:, 1], z)
    poly = _polygon([np.stack([col, row], 1)], cam)
    if poly is None:
        return None
    ox, oy = cam.project(x0, 0.0, z)
    s = cam.focal / z
    return ScenePolygon(label, poly, float(z), 'flat',
                        origin=(float(ox), float(oy)), scale=(s, s),
                        colours=colours)


@dataclass
class Street:
    """Lateral layout of a street, metres (``X``; negative is left).

    Attributes:
        road (tuple): ``(left, right)`` road edges.
        facade (tuple): ``(left, right)`` facade planes.
        end (float): Depth of the building row closing the street.
    """
    road: Tuple[float, float]
    facade: Tuple[float, float]
    end: float


def _stuff(cam: SceneCamera, st: Street, rng: np.random.Generator
           ) -> List[ScenePolygon]:
    """Sky, the far building row, sidewalks, road and the side facades,
    back to front."""
    h, w, hz = cam.height, cam.width, cam.horizon
    out = [ScenePolygon('sky', _polygon([np.array(
        [(0, 0), (w, 0), (w, hz + 1), (0, hz + 1)], float)], cam),
        SKY_DEPTH, 'sky')]
    # the row of buildings closing the street, random heights
    x = st.facade[0]
    while x < st.facade[1]:
        bw = rng.uniform(8, 25)
        out.append(_flat('building', x, x + bw, 0, rng.uniform(8, 30),
                         st.end, cam,
                         colours=(BUILDING_PAINT[rng.integers(6)], )))
        x += bw
    out.append(ScenePolygon('sidewalk', _polygon([np.array(
        [(0, hz), (w, hz), (w, h), (0, h)], float)], cam), float('nan'),
        'ground'))
    # the road: a band of the ground plane from 0.3 m to the street's end
    (xl, xr), near = st.road, 0.3
    col, row = cam.project([xl, xr, xr, xl], 0.0,
                           [st.end, st.end, near, near])
    out.append(ScenePolygon('road', _polygon([np.stack([col, row], 1)], cam),
                            float('nan'), 'ground',
                            marks=((xl + xr) / 2, xl + 0.3, xr - 0.3)))
    # facades along both sides, far to near: buildings and some hedges
    for side in (0, 1):
        x_p, z = st.facade[side], 1.0
        segs = []
        while z < st.end:
            length = rng.uniform(8, 30)
            hedge = rng.random() < 0.2
            label = 'vegetation' if hedge else 'building'
            top = rng.uniform(2.5, 8) if hedge else rng.uniform(6, 24)
            z1 = min(z + length, st.end)
            col, row = cam.project(x_p, [0, top, top, 0], [z, z, z1, z1])
            poly = _polygon([np.stack([col, row], 1)], cam)
            if poly is not None:
                segs.append(ScenePolygon(
                    label, poly, float('nan'), 'facade', plane_x=x_p,
                    colours=(BUILDING_PAINT[rng.integers(6)], )))
            z = z1
        out += segs[::-1]
    return out


def _props(cam: SceneCamera, st: Street, rng: np.random.Generator
           ) -> List[ScenePolygon]:
    """Poles (some with a sign) and trees on the sidewalks."""
    out = []
    for side, sign in ((0, -1), (1, 1)):
        curb = st.road[side] + sign * 0.4
        z = rng.uniform(3, 20)
        while z < min(st.end, 150):
            hgt = rng.uniform(4, 9)
            out.append(_flat('pole', curb - 0.08, curb + 0.08, 0, hgt, z,
                             cam))
            if rng.random() < 0.4:
                out.append(_flat('traffic sign', curb - 0.3, curb + 0.3,
                                 2.2, 2.8, z - 0.05, cam))
            z += rng.uniform(15, 40)
        if rng.random() < 0.5:
            z = rng.uniform(4, 15)
            walk = abs(st.facade[side] - st.road[side])
            while z < min(st.end, 150):
                x = st.road[side] + sign * rng.uniform(
                    0.8, max(walk - 1, 0.9))
                r = rng.uniform(1.5, 3.0)
                cy = rng.uniform(3.5, 6.0)
                ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
                rad = r * rng.uniform(0.8, 1.2, 24)
                crown = np.stack([x + rad * np.cos(ang),
                                  cy + 0.8 * rad * np.sin(ang)], 1)
                for poly in (_flat('vegetation', x - 0.15, x + 0.15, 0, cy,
                                   z, cam, colours=((95, 75, 55), )),
                             _flat('vegetation', x - r, x + r, cy - r,
                                   cy + r, z - 0.05, cam, loop=crown)):
                    out.append(poly)
                z += rng.uniform(8, 20)
    return [p for p in out if p is not None]


@functools.lru_cache(maxsize=None)
def _width(cls: str, view: str) -> float:
    x0, _, x1, _ = extent(SILHOUETTES[(cls, view)])
    return x1 - x0


def _place(cam: SceneCamera, cls: str, x: float, z: float, along: bool,
           rng: np.random.Generator) -> Tuple[str, tuple, tuple]:
    """View and metre-to-pixel frame of an object at ``(x, z)``.

    An object moving or parked along the street (``along``) shows its
    rear, plus its side foreshortened when that side's projection is the
    wider (a three-quarter view drawn as a squeezed side view, rear end
    nearest). One crossing the street shows its side at full length.

    Returns:
        tuple: ``view``, ``origin`` (pixel of the frame's origin) and
        ``scale`` (pixels per metre, ``sx < 0`` mirrored).
    """
    sy = cam.focal / z
    col, bottom = cam.project(x, 0.0, z)
    length, rear = _width(cls, 'side'), _width(cls, 'rear')
    if not along:
        sx = sy if rng.random() < 0.5 else -sy
        return 'side', (float(col - sx * length / 2), float(bottom)), (sx, sy)
    side_px = cam.focal * abs(x) * (1 / z - 1 / (z + length))
    rear_px = cam.focal * rear / z
    if side_px <= rear_px:
        return 'rear', (float(col - sy * rear / 2), float(bottom)), (sy, sy)
    sx = (side_px + rear_px) / length
    if x > 0:  # the rear end is nearest, on the right: mirrored
        return 'side', (float(col + sy * rear / 2), float(bottom)), (-sx, sy)
    return 'side', (float(col - sy * rear / 2), float(bottom)), (sx, sy)


@functools.lru_cache(maxsize=None)
def _height(cls: str) -> float:
    return extent(SILHOUETTES[(cls, 'side')])[3]


#: Where a rider sits on each two-wheeler, per view: metre offset of the
#: rider silhouettes (drawn for a bicycle) in the vehicle's frame.
RIDER_OFFSET = {('bicycle', 'side'): (0.0, 0.0),
                ('bicycle', 'rear'): (0.0, 0.0),
                ('motorcycle', 'side'): (0.1, 0.1),
                ('motorcycle', 'rear'): (0.1, 0.1)}


def _object(cam: SceneCamera, label: str, loops: Sequence[np.ndarray],
            z: float, view: str, origin: tuple, scale: tuple,
            colours: tuple, look: Optional[Sequence[np.ndarray]] = None
            ) -> Optional[ScenePolygon]:
    """Project an object's metre loops (and painted ``look`` loops) into
    the image."""
    (ox, oy), (sx, sy) = origin, scale

    def project(lps):
        return _polygon([np.stack([ox + sx * lp[:, 0], oy - sy * lp[:, 1]],
                                  1) for lp in lps], cam)

    poly = project(loops)
    if poly is None:
        return None
    return ScenePolygon(label, poly, float(z), 'object', origin=origin,
                        scale=scale, view=view, colours=colours,
                        look=None if look is None else project(look))


def _pick(palette, rng):
    return palette[int(rng.integers(len(palette)))]


def _colours(cls: str, rng: np.random.Generator) -> tuple:
    if cls in ('person', 'rider'):
        return (_pick(CLOTHES, rng), _pick(TROUSERS, rng), _pick(SKIN, rng))
    palette = dict(car=CAR_PAINT, truck=TRUCK_PAINT, bus=BUS_PAINT,
                   train=TRAIN_PAINT).get(cls, CLOTHES)
    return (_pick(palette, rng), )


class _Objects:
    """Collects the objects of a scene (depth-sorted later)."""

    def __init__(self, cam: SceneCamera, rng: np.random.Generator,
                 min_height_px: float = MIN_HEIGHT_PX):
        self.cam, self.rng, self.polys = cam, rng, []
        self.min_height_px = min_height_px

    def add(self, cls: str, x: float, z: float, along: bool,
            rider: bool = False) -> bool:
        """Place ``cls`` at ``(x, z)`` metres (with a rider on a
        two-wheeler when ``rider``); False when it is too small, behind the
        camera's near limit or outside the image."""
        cam, rng = self.cam, self.rng
        if z < MIN_DEPTH or \
                cam.focal * _height(cls) / z < self.min_height_px:
            return False
        view, origin, scale = _place(cam, cls, x, z, along, rng)
        poly = _object(cam, cls, SILHOUETTES[(cls, view)], z, view, origin,
                       scale, _colours(cls, rng), LOOKS.get((cls, view)))
        if poly is None:
            return False
        self.polys.append(poly)
        if rider:
            dx, dy = RIDER_OFFSET[(cls, view)]
            loops = [lp + np.array([dx, dy]) for lp in
                     SILHOUETTES[('rider', view)]]
            # just in front of its vehicle, so drawn over it
            poly = _object(cam, 'rider', loops, z - 0.05, view, origin,
                           scale, _colours('rider', rng))
            if poly is not None:
                self.polys.append(poly)
        return True

    def group(self, base: str, x: float, z: float) -> None:
        """A crowd region of ``base`` objects."""
        s = self.cam.focal / z
        col, bottom = self.cam.project(x, 0.0, z)
        loops = group_loops(base, self.rng)
        width = extent(loops)[2]
        poly = _object(self.cam, base + 'group', loops, z, 'side',
                       (float(col - s * width / 2), float(bottom)), (s, s),
                       _colours(base, self.rng))
        if poly is not None:
            self.polys.append(poly)

    def classes(self) -> set:
        return {p.label for p in self.polys}


def _depth(rng: np.random.Generator, lo: float = MIN_DEPTH,
           hi: float = MAX_DEPTH) -> float:
    """Log-uniform depth: as many objects in 6-12 m as in 60-120 m."""
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def _fill(objs: _Objects, st: Street, density: float) -> None:
    """Sample the objects of a street (see the module docstring)."""
    rng = objs.rng
    (xl, xr), (fl, fr) = st.road, st.facade

    def walk_x(side):  # a point on the sidewalk of that side
        edge, fac = (xl, fl) if side == 0 else (xr, fr)
        return edge + (fac - edge) * rng.uniform(0.15, 0.85)

    for side, edge in ((0, xl + 1.1), (1, xr - 1.1)):  # parked rows
        if rng.random() < 0.8:
            z, z_end = rng.uniform(5.5, 15), rng.uniform(40, 140)
            while z < z_end:
                cls = 'truck' if rng.random() < 0.08 else 'car'
                if rng.random() < 0.85 * min(density, 1.0):
                    objs.add(cls, edge, z, along=True)
                z += _width(cls, 'side') + rng.uniform(0.3, 2.0)
    for _ in range(rng.poisson(MEAN_COUNTS['traffic'] * density)):
        cls = rng.choice(['car', 'truck', 'bus', 'train'],
                         p=[0.7, 0.12, 0.1, 0.08])
        objs.add(str(cls), rng.uniform(xl + 1.5, xr - 1.5), _depth(rng),
                 along=True)
    for _ in range(rng.poisson(MEAN_COUNTS['pedestrians'] * density)):
        z = _depth(rng, hi=90.0)
        on_road = rng.random() < 0.25
        x = rng.uniform(xl, xr) if on_road else walk_x(int(rng.integers(2)))
        objs.add('person', x, z, along=not on_road and rng.random() < 0.6)
        for _ in range(int(rng.integers(0, 4)) if rng.random() < 0.3 else 0):
            objs.add('person', x + rng.uniform(-1.0, 1.0),  # a companion
                     z + rng.uniform(-1.5, 1.5), along=rng.random() < 0.5)
    for _ in range(rng.poisson(MEAN_COUNTS['cyclists'] * density)):
        cls = 'bicycle' if rng.random() < 0.7 else 'motorcycle'
        x = (xl + rng.uniform(0.6, 1.5) if rng.random() < 0.5
             else xr - rng.uniform(0.6, 1.5))
        objs.add(cls, x, _depth(rng, hi=80.0), along=rng.random() < 0.6,
                 rider=True)
    for _ in range(rng.poisson(MEAN_COUNTS['parked_bicycles'] * density)):
        side = int(rng.integers(2))
        x, z = walk_x(side), _depth(rng, hi=60.0)
        for k in range(int(rng.integers(1, 5))):  # a rack: 0.6 m apart
            objs.add('bicycle', x, z + 0.6 * k, along=False)


def _guarantee(objs: _Objects, st: Street) -> None:
    """Add a near-ish instance of each class the scene still lacks."""
    rng = objs.rng
    (xl, xr) = st.road
    for cls in INSTANCE_CLASSES:
        if cls in objs.classes():
            continue
        for _ in range(20):  # retry positions that fall out of the image
            z = _depth(rng, 8.0, 35.0)
            if cls == 'person':
                x, along = st.facade[1] * rng.uniform(0.0, 0.9), False
            elif cls == 'bicycle':
                x, along = rng.uniform(xl, xr), False
            else:
                x, along = rng.uniform(xl + 1, xr - 1), rng.random() < 0.5
            if cls == 'rider':
                vehicle = 'motorcycle' if rng.random() < 0.3 else 'bicycle'
                if objs.add(vehicle, x, z, along, rider=True):
                    break
            elif objs.add(cls, x, z, along, rider=cls == 'motorcycle'):
                break


def sample_street(cam: SceneCamera, rng: np.random.Generator) -> Street:
    """Random road and sidewalk widths and street length."""
    road = (-rng.uniform(3.5, 9), rng.uniform(3.5, 9))
    facade = (road[0] - rng.uniform(2.5, 6), road[1] + rng.uniform(2.5, 6))
    return Street(road, facade, float(rng.uniform(150, 350)))


def sample_scene(cam: SceneCamera, rng: np.random.Generator,
                 empty: bool = False, crowd: bool = False,
                 density: float = 1.0,
                 min_height_px: float = MIN_HEIGHT_PX) -> List[ScenePolygon]:
    """Sample one scene, polygons ordered back to front.

    Every non-empty scene holds each of the 8 classes at least once (so a
    tiny val split has ground truth for every class): missing ones are
    added at 8-35 m after the random ones.

    Args:
        cam (SceneCamera): Camera of the image size.
        rng (np.random.Generator): Source of randomness.
        empty (bool): Draw no instances (stuff, poles and trees only).
        crowd (bool): Add one crowd region (``persongroup``, ``cargroup``
            or ``bicyclegroup``).
        density (float): Scale of the mean object counts
            (:data:`MEAN_COUNTS`, parked rows).
        min_height_px (float): Objects shorter than this (pixels, standing
            height before occlusion) are not drawn.

    Returns:
        list[ScenePolygon]: Stuff first, then poles, trees and objects far
        to near.
    """
    st = sample_street(cam, rng)
    polys = [p for p in _stuff(cam, st, rng) if p.polygon is not None]
    front = _props(cam, st, rng)
    if not empty:
        objs = _Objects(cam, rng, min_height_px)
        _fill(objs, st, density)
        _guarantee(objs, st)
        if crowd:
            base = GROUP_CLASSES[int(rng.integers(len(GROUP_CLASSES)))]
            objs.group(base, rng.uniform(st.road[0], st.facade[1] * 0.7),
                       rng.uniform(15.0, 45.0))
        front += objs.polys
    front.sort(key=lambda p: -p.depth)  # painter's order: far first
    return polys + front
