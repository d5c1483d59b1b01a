"""Random street scenes for the Cityscapes-like stand-in dataset.

A scene is a list of polygons in Cityscapes' ``*_gtFine_polygons.json``
order (drawn first = furthest back), each with a label name, a depth and the
pixel box used to scale its texture. Geometry follows a pinhole camera at
height :data:`CAMERA_HEIGHT` looking along a flat road, so an object's pixel
size is ``focal * size_m / depth`` and its ground contact row is
``horizon + focal * CAMERA_HEIGHT / depth``: distant objects are small and
sit near the horizon, as in real driving images.

Nothing here draws pixels; :mod:`.cityscapes_like` rasterises scenes with
cityscapesscripts' own label/instance renderers.
"""
from dataclasses import dataclass, field
from typing import Dict, List, Tuple

import numpy as np
from cityscapesscripts.helpers.labels import labels

#: The 8 Cityscapes instance classes evaluated by the benchmark, in label-id
#: order (person, rider, car, truck, bus, train, motorcycle, bicycle).
INSTANCE_CLASSES: Tuple[str, ...] = tuple(
    lab.name for lab in labels if lab.hasInstances and not lab.ignoreInEval)

#: Camera height above the road, metres.
CAMERA_HEIGHT = 1.5
#: Focal length as a fraction of the image width (about 64 deg horizontal
#: field of view; Cityscapes' is about 50 deg at 2048 px).
FOCAL_PER_WIDTH = 0.8
#: Horizon row as a fraction of the image height.
HORIZON = 0.42
#: Depth of the sky, metres; also the far clamp of the road plane. Fits the
#: 16-bit centimetre depth PNG (max 655.35 m).
SKY_DEPTH = 600.0
#: Depth range of objects, metres (log-uniform in between).
MIN_DEPTH, MAX_DEPTH = 6.0, 120.0
#: Smallest object height drawn, pixels (smaller ones vanish in rasterising).
MIN_HEIGHT_PX = 4.0

#: Real-world (height, width) of each class, metres.
CLASS_SIZE_M: Dict[str, Tuple[float, float]] = {
    'person': (1.75, 0.6),
    'rider': (1.8, 0.9),
    'car': (1.5, 4.2),
    'truck': (3.2, 7.0),
    'bus': (3.2, 11.0),
    'train': (4.0, 20.0),
    'motorcycle': (1.3, 2.0),
    'bicycle': (1.1, 1.8),
}

#: Class silhouettes in a unit box (x right, y down, y = 1 on the road).
#: Each class has its own outline so a detector can tell them apart even in
#: fog, where colour fades first.
CLASS_SHAPES: Dict[str, np.ndarray] = {
    name: np.asarray(pts, dtype=np.float64)
    for name, pts in {
        'person': [(.35, 0), (.65, 0), (.65, .18), (.9, .25), (.85, .6),
                   (.7, .6), (.7, 1), (.55, 1), (.5, .65), (.45, 1),
                   (.3, 1), (.3, .6), (.15, .6), (.1, .25), (.35, .18)],
        'rider': [(.4, 0), (.6, 0), (.6, .15), (.8, .2), (.75, .5),
                  (1, .6), (1, 1), (0, 1), (0, .6), (.25, .5), (.2, .2),
                  (.4, .15)],
        'car': [(0, .45), (.2, .4), (.3, .05), (.75, .05), (.85, .4),
                (1, .45), (1, .9), (.85, 1), (.75, .9), (.3, .9), (.2, 1),
                (0, .9)],
        'truck': [(0, 0), (.7, 0), (.7, .25), (.85, .25), (1, .55),
                  (1, 1), (0, 1)],
        'bus': [(.03, 0), (.97, 0), (1, .06), (1, 1), (0, 1), (0, .06)],
        'train': [(.12, 0), (1, 0), (1, 1), (0, 1), (0, .45)],
        'motorcycle': [(0, .5), (.3, .3), (.45, 0), (.6, .3), (1, .4),
                       (1, 1), (.7, .7), (.3, .7), (0, 1)],
        'bicycle': [(0, 1), (.2, .4), (.5, .15), (.8, .4), (1, 1),
                    (.85, 1), (.7, .55), (.5, .4), (.3, .55), (.15, 1)],
    }.items()
}

#: Classes that appear as crowd ("group") regions, as in Cityscapes.
GROUP_CLASSES = ('person', 'car', 'bicycle')


@dataclass
class ScenePolygon:
    """One polygon of a scene.

    Attributes:
        label (str): Cityscapes label name (``'car'``, ``'cargroup'``,
            ``'road'``...).
        polygon (np.ndarray): Integer vertices, ``int64[K, 2]`` (x, y) in
            pixels, inside the image.
        depth (float): Distance to the camera, metres (``nan`` for the road
            and sidewalk, whose depth follows the ground plane per row).
        box (tuple): ``(x0, y0, w, h)`` pixel box the texture is laid on.
    """
    label: str
    polygon: np.ndarray
    depth: float
    box: Tuple[float, float, float, float]


@dataclass
class SceneCamera:
    """Pinhole camera of the scenes of one image size.

    Attributes:
        height (int): Image height, pixels.
        width (int): Image width, pixels.
        focal (float): Focal length, pixels.
        horizon (float): Horizon row, pixels.
    """
    height: int
    width: int
    focal: float = field(init=False)
    horizon: float = field(init=False)

    def __post_init__(self):
        self.focal = FOCAL_PER_WIDTH * self.width
        self.horizon = HORIZON * self.height

    def ground_depth(self) -> np.ndarray:
        """Depth of the road plane at each row, ``float64[H]``, metres.

        Rows at or above the horizon get :data:`SKY_DEPTH`.
        """
        rows = np.arange(self.height) + 0.5 - self.horizon
        with np.errstate(divide='ignore'):
            depth = self.focal * CAMERA_HEIGHT / rows
        return np.where(rows > 0, np.minimum(depth, SKY_DEPTH), SKY_DEPTH)


def _clip(poly: np.ndarray, cam: SceneCamera) -> np.ndarray:
    """Round to integer pixels and clip into the image (Cityscapes'
    polygons are integer and inside the image)."""
    poly = np.rint(poly).astype(np.int64)
    poly[:, 0] = poly[:, 0].clip(0, cam.width - 1)
    poly[:, 1] = poly[:, 1].clip(0, cam.height - 1)
    return poly


def _background(cam: SceneCamera, rng: np.random.Generator
                ) -> List[ScenePolygon]:
    """Sky, buildings, vegetation, sidewalks and road (the 'stuff')."""
    h, w, hz = cam.height, cam.width, cam.horizon
    out = [
        ScenePolygon('sky', _clip(np.array(
            [(0, 0), (w, 0), (w, hz), (0, hz)], float), cam), SKY_DEPTH,
            (0, 0, w, hz))
    ]
    # a skyline of buildings (and some trees) standing on the horizon
    x = 0.0
    while x < w:
        bw = rng.uniform(0.08, 0.25) * w
        bh = rng.uniform(0.15, 0.9) * hz
        name = 'vegetation' if rng.random() < 0.25 else 'building'
        poly = np.array([(x, hz - bh), (x + bw, hz - bh), (x + bw, hz),
                         (x, hz)])
        out.append(ScenePolygon(name, _clip(poly, cam),
                                float(rng.uniform(80, 250)),
                                (x, hz - bh, bw, bh)))
        x += bw
    # the road is a trapezoid to the vanishing point; sidewalks either side
    vx = w * rng.uniform(0.4, 0.6)
    side = np.array([(0, hz), (w, hz), (w, h), (0, h)], float)
    road = np.array([(vx - 2, hz), (vx + 2, hz), (w * 1.3, h), (-w * .3, h)])
    out.append(ScenePolygon('sidewalk', _clip(side, cam), float('nan'),
                            (0, hz, w, h - hz)))
    out.append(ScenePolygon('road', _clip(road, cam), float('nan'),
                            (0, hz, w, h - hz)))
    return out


def _object(name: str, depth: float, cx: float, cam: SceneCamera,
            shape: np.ndarray) -> ScenePolygon:
    """Place a unit-box silhouette of real size ``CLASS_SIZE_M[name]`` at
    ``depth`` metres with its bottom centre at column ``cx``."""
    base = name[:-len('group')] if name.endswith('group') else name
    hm, wm = CLASS_SIZE_M[base]
    ph, pw = cam.focal * hm / depth, cam.focal * wm / depth
    if name.endswith('group'):
        pw *= 3.0  # a crowd spans several objects side by side
    bottom = cam.horizon + cam.focal * CAMERA_HEIGHT / depth
    x0, y0 = cx - pw / 2, bottom - ph
    poly = shape * np.array([pw, ph]) + np.array([x0, y0])
    return ScenePolygon(name, _clip(poly, cam), float(depth), (x0, y0, pw, ph))


def _group_shape(rng: np.random.Generator) -> np.ndarray:
    """A crowd outline: a box with a bumpy top (several heads/roofs)."""
    n = int(rng.integers(3, 6))
    xs = np.linspace(0, 1, 2 * n + 1)
    tops = np.where(np.arange(2 * n + 1) % 2 == 0, 0.25, 0.0)
    tops = tops + rng.uniform(0, 0.1, size=tops.shape)
    top = np.stack([xs, tops], 1)
    return np.concatenate([top, [(1, 1), (0, 1)]])


def sample_scene(cam: SceneCamera, rng: np.random.Generator,
                 empty: bool = False, crowd: bool = False,
                 max_extra: int = 6) -> List[ScenePolygon]:
    """Sample one scene, polygons ordered back to front.

    Every non-empty scene holds each of the 8 classes at least once (so the
    tiny val split has ground truth for every class), plus up to
    ``max_extra`` more objects. Depths are log-uniform in
    [:data:`MIN_DEPTH`, :data:`MAX_DEPTH`] (many scales; two objects are
    forced past 60 m so every scene has small distant ones). The 8 take one
    column slot each; half of the extra objects are placed next to an
    earlier one so that they occlude each other.

    Args:
        cam (SceneCamera): Camera of the image size.
        rng (np.random.Generator): Source of randomness.
        empty (bool): Draw no instances (stuff only).
        crowd (bool): Add one crowd region (``persongroup``, ``cargroup``
            or ``bicyclegroup``).
        max_extra (int): Most objects added on top of the 8.

    Returns:
        list[ScenePolygon]: Stuff first, then objects far to near.
    """
    polys = _background(cam, rng)
    if empty:
        return polys
    names = list(INSTANCE_CLASSES) + list(
        rng.choice(INSTANCE_CLASSES, size=int(rng.integers(0, max_extra + 1))))
    # the 8 guaranteed objects get one of 8 column slots each, so that they
    # are rarely hidden entirely; extra objects go anywhere
    slots = rng.permutation(len(INSTANCE_CLASSES))
    objs = []
    for i, name in enumerate(names):
        hm, wm = CLASS_SIZE_M[name]
        guaranteed = i < len(INSTANCE_CLASSES)
        # nearest depth keeping the object within 35% (guaranteed ones) or
        # 80% of the width and its bottom inside the image; farthest
        # keeping it MIN_HEIGHT_PX tall
        max_w = (0.35 if guaranteed else 0.8) * cam.width
        near = max(MIN_DEPTH, cam.focal * wm / max_w,
                   cam.focal * CAMERA_HEIGHT / (cam.height - cam.horizon))
        far = max(near, min(MAX_DEPTH, cam.focal * hm / MIN_HEIGHT_PX))
        lo = max(near, 60.0) if i < 2 and far > 60.0 else near
        depth = float(np.exp(rng.uniform(np.log(lo), np.log(far))))
        if guaranteed:
            cx = (slots[i] + rng.uniform(0.2, 0.8)) / len(slots) * cam.width
        elif rng.random() < 0.5:
            cx = objs[int(rng.integers(len(objs)))].box[0] + rng.uniform(
                -0.5, 1.5) * cam.focal * wm / depth  # overlap a neighbour
        else:
            cx = rng.uniform(0.05, 0.95) * cam.width
        objs.append(_object(name, depth, cx, cam, CLASS_SHAPES[name]))
    if crowd:
        name = GROUP_CLASSES[int(rng.integers(len(GROUP_CLASSES)))]
        depth = float(rng.uniform(20.0, 50.0))
        objs.append(
            _object(name + 'group', depth, rng.uniform(0.2, 0.8) * cam.width,
                    cam, _group_shape(rng)))
    objs.sort(key=lambda p: -p.depth)  # painter's order: far first
    return polys + objs
