"""Object silhouettes of the generated street scenes, in metres.

A silhouette is a list of closed loops in a side (``'side'``) or rear/front
(``'rear'``) view, ``x`` to the right from the object's left end, ``y`` up
from the road, metres. The loops are joined into ONE polygon per object (a
Cityscapes instance is one polygon) by :func:`join_loops` and filled with
the even-odd rule of PIL's ``ImageDraw.polygon`` (the renderer of
cityscapesscripts).

Two silhouettes per object, as in Cityscapes:

* :data:`SILHOUETTES`, the annotated outline: one loop without holes
  ("labeled foreground objects must never have holes": background seen
  through a bicycle's wheels belongs to the bicycle, Cityscapes' labeling
  policy). Thin parts stay thin: limbs, a rider's legs, handlebars,
  mirrors, a bicycle seen from behind (tyre and stem under a bar), a
  tram's pantograph.
* :data:`LOOKS`, what is painted where it differs from the outline: a
  bicycle's tyres are rings and its frame a closed loop of tubes, so the
  background shows through them (inner loops are holes under even-odd);
  those pixels are labelled bicycle but coloured by what is behind.
"""
from typing import Dict, List, Tuple

import numpy as np

Loop = np.ndarray  # float64[K, 2], (x, y) metres
#: Wheel geometry of the two-wheelers, metres: centres x (side view),
#: radius, tyre width. Shared with the texturing (tyres are black).
BICYCLE_WHEELS = ((0.35, 1.40), 0.35, 0.07)
MOTORCYCLE_WHEELS = ((0.35, 1.65), 0.32, 0.11)


def ellipse(cx: float, cy: float, rx: float, ry: float, n: int = 16,
            reverse: bool = False) -> Loop:
    """``n`` points on an ellipse, counter-clockwise (y up) unless
    ``reverse``."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    if reverse:
        t = t[::-1]
    return np.stack([cx + rx * np.cos(t), cy + ry * np.sin(t)], 1)


def head(cx: float, cy: float, clockwise: bool) -> List[Tuple[float, float]]:
    """Points of a head (0.2 x 0.24 m) centred at ``(cx, cy)``, from its
    lower right over the top to its lower left (or the other way when
    ``clockwise``), for a body outline passing through the neck."""
    t = np.deg2rad(np.linspace(-60, 240, 9))
    if clockwise:
        t = t[::-1]
    return list(zip(cx + 0.1 * np.cos(t), cy + 0.12 * np.sin(t)))


def ring(cx: float, cy: float, r: float, width: float,
         n: int = 20) -> List[Loop]:
    """A tyre: outer circle and the inner one reversed (a hole)."""
    return [ellipse(cx, cy, r, r, n),
            ellipse(cx, cy, r - width, r - width, n, reverse=True)]


def bar(p0: Tuple[float, float], p1: Tuple[float, float],
        width: float) -> Loop:
    """A straight tube of ``width`` metres from ``p0`` to ``p1``."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = p1 - p0
    n = np.array([-d[1], d[0]]) / max(np.hypot(*d), 1e-9) * width / 2
    return np.stack([p0 + n, p1 + n, p1 - n, p0 - n])


def inset(poly: Loop, t: float) -> Loop:
    """A convex counter-clockwise polygon moved inwards by ``t`` metres
    (its edges offset, consecutive ones intersected)."""
    p, q = poly, np.roll(poly, -1, 0)
    d = q - p
    n = np.stack([-d[:, 1], d[:, 0]], 1) / np.hypot(d[:, 0], d[:, 1])[:, None]
    a = p + n * t  # a point of each offset edge; direction d
    out = []
    for i in range(len(p)):
        j = (i - 1) % len(p)  # previous edge meets edge i at vertex i
        m = np.stack([d[j], -d[i]], 1)
        s = np.linalg.solve(m, a[i] - a[j])[0]
        out.append(a[j] + s * d[j])
    return np.asarray(out)


def tube_loop(poly: Loop, width: float) -> List[Loop]:
    """A closed frame of tubes along a convex polygon's edges."""
    poly = np.asarray(poly, float)
    (ax, ay), (bx, by) = poly[1] - poly[0], poly[2] - poly[1]
    if ax * by - ay * bx < 0:  # clockwise (NumPy 2 has no 2-D np.cross)
        poly = poly[::-1]
    return [inset(poly, -width / 2), inset(poly, width / 2)[::-1]]


def join_loops(loops: List[Loop]) -> Loop:
    """One polygon visiting every loop.

    Zero-width bridges chain the loops (each loop entered at its vertex
    nearest to where the previous one was entered) and are walked back at
    the end, so each bridge is traversed twice and the even-odd fill is the
    XOR of the loops, plus the bridges' one-pixel outlines.
    """
    parts, entries = [], []
    for loop in loops:
        loop = np.asarray(loop, float)
        if entries:
            k = int(np.argmin(np.hypot(*(loop - entries[-1]).T)))
            loop = np.roll(loop, -k, 0)
        entries.append(loop[0])
        parts += [loop, loop[:1]]
    back = np.asarray(entries[-2::-1]).reshape(-1, 2)  # bridges back
    return np.concatenate(parts + [back])


def _person(stride: float) -> List[Loop]:
    """A standing person, front/back view, 0.5 x 1.75 m, with arms apart
    from the torso and legs apart by ``stride`` metres at the feet."""
    s = stride / 2
    outline = [
        (0.12 - s, 0.0), (0.23 - s, 0.0), (0.25, 0.78), (0.27 + s, 0.0),
        (0.38 + s, 0.0), (0.38, 0.9), (0.38, 1.35), (0.40, 1.35),
        (0.41, 0.85), (0.47, 0.85), (0.47, 1.40), (0.38, 1.48),
        (0.29, 1.50)] + head(0.25, 1.63, False) + [
        (0.21, 1.50), (0.12, 1.48), (0.03, 1.40),
        (0.03, 0.85), (0.09, 0.85), (0.10, 1.35), (0.12, 1.35),
        (0.12, 0.9)
    ]
    return [np.asarray(outline)]


def _rider_side() -> List[Loop]:
    """A cyclist seated on a two-wheeler 1.75 m long, side view."""
    back = [(0.62, 0.92), (0.78, 1.44), (0.88, 1.50)]
    front = [(1.00, 1.47), (1.26, 1.06), (1.24, 1.00), (0.98, 1.30),
             (0.96, 1.08), (1.12, 0.86), (1.00, 0.40), (1.07, 0.36),
             (0.90, 0.33), (0.94, 0.80), (0.66, 0.86)]
    body = back + head(0.93, 1.62, True) + front
    return [np.asarray(body)]


def _rider_rear() -> List[Loop]:
    """A cyclist seen from behind, legs either side of the wheel."""
    right = [(0.12, 0.35), (0.19, 0.35), (0.23, 0.85), (0.37, 0.85),
             (0.41, 0.35), (0.48, 0.35), (0.44, 0.95), (0.46, 1.30),
             (0.58, 1.02), (0.62, 1.05), (0.44, 1.48), (0.35, 1.50)]
    left = [(0.25, 1.50), (0.16, 1.48), (-0.02, 1.05), (0.02, 1.02),
            (0.14, 1.30), (0.16, 0.95)]
    body = right + head(0.30, 1.63, False) + left
    return [np.asarray(body)]


def _bicycle_look() -> List[Loop]:
    """What a bicycle's side shows: tyre rings, a frame of tubes, fork,
    handlebar and saddle (background through the rest)."""
    (xr, xf), r, tyre = BICYCLE_WHEELS
    frame = [(xr, r), (0.85, 0.30), (1.25, 0.88), (0.75, 0.88)]
    return (ring(xr, r, r, tyre) + ring(xf, r, r, tyre)
            + tube_loop(frame, 0.04)
            + [bar((1.25, 0.88), (xf, r), 0.035),      # fork
               bar((1.18, 1.02), (1.30, 0.96), 0.03),  # handlebar
               bar((0.64, 0.93), (0.84, 0.93), 0.05)])  # saddle


def _arc(cx: float, cy: float, r: float, deg0: float,
         deg1: float, n: int = 9) -> List[Tuple[float, float]]:
    t = np.deg2rad(np.linspace(deg0, deg1, n))
    return list(zip(cx + r * np.cos(t), cy + r * np.sin(t)))


def _two_wheeler(wheels, top: List[tuple], bottom: List[tuple]
                 ) -> List[Loop]:
    """A two-wheeler's outline without holes: the rear wheel from its
    lower right round the back to its top, the ``top`` line, the front
    wheel from its top round the front to its lower left, ``bottom``."""
    (xr, xf), r, _ = wheels
    return [np.asarray(_arc(xr, r, r, -50, -270) + top
                       + _arc(xf, r, r, 90, -130) + bottom)]


def _bicycle_side() -> List[Loop]:
    # saddle, top tube, handlebar; chainring between the wheels
    return _two_wheeler(BICYCLE_WHEELS,
                        [(0.62, 0.90), (0.64, 0.96), (0.84, 0.96),
                         (0.80, 0.90), (1.20, 0.90), (1.16, 1.04),
                         (1.32, 0.99), (1.28, 0.86)],
                        [(0.95, 0.22), (0.75, 0.22)])


def _bicycle_rear() -> List[Loop]:
    """A bicycle from behind: a tyre and stem under a 0.6 m handlebar."""
    return [np.asarray([(0.275, 0.0), (0.325, 0.0), (0.325, 0.96),
                        (0.60, 0.96), (0.60, 1.00), (0.0, 1.00),
                        (0.0, 0.96), (0.275, 0.96)])]


def _motorcycle_side() -> List[Loop]:
    # seat, tank, windscreen; engine between the wheels
    return _two_wheeler(MOTORCYCLE_WHEELS,
                        [(0.0, 0.68), (0.0, 0.80), (0.55, 0.95),
                         (1.10, 0.95), (1.33, 1.18), (1.48, 1.18),
                         (1.45, 0.90), (1.72, 0.68)],
                        [(1.28, 0.20), (0.72, 0.20)])


def _motorcycle_rear() -> List[Loop]:
    """A motorcycle from behind: tyre, body, handlebar with mirrors."""
    return [np.asarray([
        (0.335, 0.0), (0.465, 0.0), (0.465, 0.35), (0.58, 0.35),
        (0.62, 0.95), (0.43, 0.95), (0.43, 1.08), (0.80, 1.08),
        (0.80, 1.12), (0.0, 1.12), (0.0, 1.08), (0.37, 1.08), (0.37, 0.95),
        (0.18, 0.95), (0.22, 0.35), (0.335, 0.35)])]


def _wheel_arch(cx: float, r: float, y: float) -> List[Tuple[float, float]]:
    """Points of a wheel bulging below the body line ``y``, right to left.
    """
    t = np.linspace(0, -np.pi, 7)
    return [(cx + r * np.cos(a), min(y, r + r * np.sin(a))) for a in t]


def _vehicle_side(length: float, height: float, top: List[tuple],
                  wheels: Tuple[float, ...], r: float) -> Loop:
    """A side view: the roof line ``top`` (left to right), a body down to
    ``r`` above the road, wheels of radius ``r`` at ``wheels`` (x)."""
    bottom = []
    for cx in sorted(wheels, reverse=True):
        bottom += _wheel_arch(cx, r, r)
    return np.asarray([(0.0, r)] + top + [(length, r)] + bottom)


def _car_rear() -> List[Loop]:
    return [np.asarray([
        (0.0, 0.12), (0.0, 0.80), (0.12, 0.86), (0.30, 1.45), (1.50, 1.45),
        (1.68, 0.86), (1.80, 0.80), (1.80, 0.12), (1.62, 0.12),
        (1.62, 0.0), (1.40, 0.0), (1.40, 0.12), (0.40, 0.12), (0.40, 0.0),
        (0.18, 0.0), (0.18, 0.12)])]


def _car_side() -> List[Loop]:
    return [_vehicle_side(4.3, 1.5, [(0.0, 0.80), (0.9, 0.92), (1.4, 1.45),
                                     (3.0, 1.45), (3.6, 0.95), (4.3, 0.85)],
                          (0.75, 3.45), 0.32)]


def _box_rear(width: float, height: float, wheel: float) -> List[Loop]:
    """A truck/bus/tram end: a box with rounded top corners over two tyre
    stubs of height ``wheel``."""
    w, h, c = width, height, 0.12 * width
    return [np.asarray([
        (0.0, wheel), (0.0, h - c), (c, h), (w - c, h), (w, h - c),
        (w, wheel), (w - 0.15, wheel), (w - 0.15, 0.0), (w - 0.5, 0.0),
        (w - 0.5, wheel), (0.5, wheel), (0.5, 0.0), (0.15, 0.0),
        (0.15, wheel)])]


def _truck_side() -> List[Loop]:
    return [_vehicle_side(7.5, 3.4, [(0.0, 3.4), (5.6, 3.4), (5.6, 2.9),
                                     (6.8, 2.9), (7.5, 1.9), (7.5, 0.9)],
                          (1.2, 2.3, 6.5), 0.5)]


def _bus_side() -> List[Loop]:
    return [_vehicle_side(12.0, 3.2, [(0.0, 3.0), (0.2, 3.2), (11.8, 3.2),
                                      (12.0, 3.0)], (2.5, 9.5), 0.5)]


def _train_side() -> List[Loop]:
    # the pantograph: a thin mast and bow on the roof
    return [_vehicle_side(25.0, 3.5, [
        (0.0, 3.2), (0.4, 3.5), (12.45, 3.5), (12.45, 4.1), (11.8, 4.1),
        (11.8, 4.16), (13.2, 4.16), (13.2, 4.1), (12.55, 4.1),
        (12.55, 3.5), (24.2, 3.5), (25.0, 2.8)], (3.0, 5.0, 20.0, 22.0),
        0.4)]


def _train_front() -> List[Loop]:
    return _box_rear(2.65, 3.5, 0.4)


#: Silhouette loops of each ``(class, view)``, metres.
SILHOUETTES: Dict[Tuple[str, str], List[Loop]] = {
    ('person', 'rear'): _person(0.0),
    ('person', 'side'): _person(0.3),  # walking: feet apart
    ('rider', 'side'): _rider_side(),
    ('rider', 'rear'): _rider_rear(),
    ('bicycle', 'side'): _bicycle_side(),
    ('bicycle', 'rear'): _bicycle_rear(),
    ('motorcycle', 'side'): _motorcycle_side(),
    ('motorcycle', 'rear'): _motorcycle_rear(),
    ('car', 'side'): _car_side(),
    ('car', 'rear'): _car_rear(),
    ('truck', 'side'): _truck_side(),
    ('truck', 'rear'): _box_rear(2.5, 3.4, 0.5),
    ('bus', 'side'): _bus_side(),
    ('bus', 'rear'): _box_rear(2.55, 3.2, 0.5),
    ('train', 'side'): _train_side(),
    ('train', 'rear'): _train_front(),
}


#: Painted loops where they differ from :data:`SILHOUETTES`.
LOOKS: Dict[Tuple[str, str], List[Loop]] = {
    ('bicycle', 'side'): _bicycle_look(),
}


def extent(loops: List[Loop]) -> Tuple[float, float, float, float]:
    """``(x_min, y_min, x_max, y_max)`` of a silhouette, metres."""
    pts = np.concatenate(loops)
    return (*pts.min(0), *pts.max(0))


def group_loops(base: str, rng: np.random.Generator) -> List[Loop]:
    """A crowd region (``persongroup``...): several overlapping members
    side by side, as one outline with a bumpy top (heads / roofs)."""
    x0, _, x1, y1 = extent(SILHOUETTES[(base, 'side')])
    n = int(rng.integers(3, 6))
    w = (x1 - x0) * 0.7
    xs = np.linspace(0, w * n, 2 * n + 1)
    tops = np.where(np.arange(2 * n + 1) % 2 == 0, 0.85, 1.0) * y1
    tops = tops * rng.uniform(0.9, 1.0, size=tops.shape)
    top = np.stack([xs, tops], 1)
    return [np.concatenate([[(0.0, 0.0)], top, [(w * n, 0.0)]])]
