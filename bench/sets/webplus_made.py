"""Builders of the ``webplus`` set's man-made kinds (see :mod:`bench.sets.webplus_shapes`).

Kinds that neither ``web`` nor ``generic`` has, in close families: three seats
(rocking, folding and lounge chairs), three lamps (chandelier, pendant and street
lamps), a shoe rack, a fence and a gate, three aircraft (fighter jet, airship,
quadcopter) and two boats (rowboat, catamaran); bridges and towers are in
:mod:`bench.sets.webplus_structures`. Each builder takes a
seeded generator and returns the parts of one model, z up, standing on z = 0, in
metres; proportions vary by up to about 40 %, part counts and styles vary with the seed.
"""

from __future__ import annotations

import numpy as np

from bench.sets.mesh_parts import Part, Rng, box, ellipsoid, hquad, quad, revolve, rod, sheet
from bench.sets.web_furniture import panel, slab, vary

__all__ = ["tube", "arc_points", "BUILDERS"]


def tube(points: np.ndarray, r: float | np.ndarray, n: int = 6) -> list[Part]:
    """Rods along the polyline ``points`` (k, 3); ``r`` one radius or (k - 1,) radii."""
    pts = np.asarray(points, dtype=float)
    radii = np.broadcast_to(np.asarray(r, dtype=float), (len(pts) - 1,))
    return [rod(pts[i], pts[i + 1], float(radii[i]), n=n) for i in range(len(pts) - 1)]


def arc_points(y0: float, y1: float, rise: float, z0: float, k: int = 8) -> np.ndarray:
    """(k + 1, 3) points of a parabolic arc in the y-z plane from ``y0`` to ``y1`` at x = 0."""
    y = np.linspace(y0, y1, k + 1)
    t = (y - y0) / (y1 - y0)
    return np.column_stack([np.zeros_like(y), y, z0 + 4 * rise * t * (1 - t)])


# --------------------------------------------------------------------------------------
# Seats
# --------------------------------------------------------------------------------------


def rocking_chair(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 0.5, 0.2), vary(rng, 0.5, 0.2), vary(rng, 0.42, 0.15)
    lift = vary(rng, 0.08, 0.4)
    parts = [slab(rng, (0, 0, h), w, d, 0.04)]
    length, rise = d * vary(rng, 1.8, 0.2), vary(rng, 0.08, 0.4)
    for sx in (-1, 1):
        arc = arc_points(-length / 2, length / 2, -rise, rise + 0.02, k=6)
        arc[:, 0] = sx * w / 2
        parts += tube(arc, 0.018)
        for sy in (-1, 1):
            parts.append(rod((sx * w / 2, sy * d / 2.5, lift), (sx * w / 2, sy * d / 2.5, h), 0.02))
    bh, tilt = vary(rng, 0.6, 0.3), rng.uniform(0.05, 0.3)
    n = int(rng.integers(3, 8))
    for x in np.linspace(-w / 2 + 0.03, w / 2 - 0.03, n):
        parts.append(rod((x, -d / 2, h), (x, -d / 2 - tilt * bh, h + bh), 0.012, n=5))
    parts.append(box((0, -d / 2 - tilt * bh, h + bh), (w + 0.04, 0.05, 0.07)))
    if rng.random() < 0.6:  # arms
        for sx in (-1, 1):
            parts.append(box((sx * w / 2, 0, h + 0.22), (0.05, d, 0.03)))
            parts.append(rod((sx * w / 2, d / 2.5, h), (sx * w / 2, d / 2.5, h + 0.22), 0.015))
    return parts


def folding_chair(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 0.45, 0.15), vary(rng, 0.45, 0.2), vary(rng, 0.45, 0.1)
    bh, r = vary(rng, 0.4, 0.3), vary(rng, 0.012, 0.3)
    parts: list[Part] = []
    for sx in (-1, 1):
        x = sx * w / 2
        parts.append(rod((x, d / 2, 0), (x, -d / 2 + 0.05, h + bh), r))  # front leg and back post
        parts.append(rod((x, -d / 2, 0), (x, d / 2 - 0.05, h), r))  # rear leg, crossing
    parts.append(hquad((0, 0, h), w, d) if rng.random() < 0.5 else box((0, 0, h), (w, d, 0.02)))
    top = h + bh * rng.uniform(0.6, 0.9)
    parts.append(quad((0, -d / 2 + 0.05 + 0.02, top), (w / 2, 0, 0), (0, 0.01, bh * 0.18)))
    for k in range(int(rng.integers(0, 3))):  # cross bars
        parts.append(rod((-w / 2, d / 2 - 0.1 * k, 0.1 + 0.05 * k), (w / 2, d / 2 - 0.1 * k,
                         0.1 + 0.05 * k), r))  # fmt: skip
    return parts


def lounge_chair(rng: Rng) -> list[Part]:
    w, length = vary(rng, 0.6, 0.2), vary(rng, 1.8, 0.2)
    h, back, foot = vary(rng, 0.35, 0.3), rng.uniform(0.35, 1.2), rng.uniform(-0.1, 0.35)
    seat = length * rng.uniform(0.45, 0.6)
    y0, y1 = length / 2, length / 2 - seat
    bl = length - seat
    profile = [(y0, h + foot * 0.5), (y1, h), (y1 - bl * np.cos(back), h + bl * np.sin(back))]
    parts: list[Part] = []
    for (ya, za), (yb, zb) in zip(profile[:-1], profile[1:], strict=True):
        c = (0, (ya + yb) / 2, (za + zb) / 2)
        if rng.random() < 0.5:
            parts.append(quad(c, (w / 2, 0, 0), (0, (ya - yb) / 2, (za - zb) / 2)))
        else:
            parts += tube(np.array([[-w / 2, ya, za], [-w / 2, yb, zb]]), 0.02)
            parts += tube(np.array([[w / 2, ya, za], [w / 2, yb, zb]]), 0.02)
            n = int(rng.integers(4, 9))
            for t in np.linspace(0, 1, n):
                y, z = ya + t * (yb - ya), za + t * (zb - za)
                parts.append(box((0, y, z), (w, 0.06, 0.015)))
    for sx in (-1, 1):
        for y in (y0 - 0.05, y1 - 0.1 * bl):
            parts.append(rod((sx * w / 2, y, 0), (sx * w / 2, y, h), 0.02))
    if rng.random() < 0.4:  # cushion
        parts.append(ellipsoid((0, (y0 + y1) / 2, h + 0.05), (w / 2, seat / 2, 0.05)))
    if rng.random() < 0.3:  # wheels at the head end
        for sx in (-1, 1):
            parts.append(ellipsoid((sx * w / 2, y1 - bl * 0.1, 0.08), (0.02, 0.08, 0.08)))
    return parts


# --------------------------------------------------------------------------------------
# Lamps
# --------------------------------------------------------------------------------------


def _shade(rng: Rng, c: tuple[float, float, float], r: float) -> Part:
    """An open shade hanging at ``c``: a dome, a cone or a drum, opening downwards."""
    style = int(rng.integers(3))
    x, y, z = c
    if style == 0:
        t = np.linspace(0, np.pi / 2, 5)
        return revolve(z - 0.8 * r + 0.8 * r * np.sin(t), np.maximum(r * np.cos(t), 0.05 * r),
                       n=14, bottom=False, c=(x, y))  # fmt: skip
    if style == 1:
        return revolve(np.array([z - r, z]), np.array([r, 0.2 * r]), n=14, bottom=False, c=(x, y))
    return revolve(np.array([z - 0.8 * r, z]), np.array([r, r]), n=14, bottom=False, top=True,
                   c=(x, y))  # fmt: skip


def chandelier(rng: Rng) -> list[Part]:
    r, drop = vary(rng, 0.4, 0.35), vary(rng, 0.5, 0.5)
    parts = [rod((0, 0, 0), (0, 0, drop), 0.01, n=5), ellipsoid((0, 0, 0), (0.06, 0.06, 0.1))]
    tiers = 1 if rng.random() < 0.6 else 2
    for t in range(tiers):
        n, rr, z = int(rng.integers(4, 11)), r * (1 - 0.4 * t), -0.05 + 0.15 * t
        for k in range(n):
            a = 2 * np.pi * (k + 0.5 * t) / n
            tip = np.array([rr * np.cos(a), rr * np.sin(a), z + 0.1])
            mid = np.array([0.5 * rr * np.cos(a), 0.5 * rr * np.sin(a), z - 0.08])
            parts += tube(np.array([[0, 0, z], mid, tip]), 0.01, n=5)
            parts.append(rod(tip, tip + [0, 0, 0.08], 0.012, n=5))
            if rng.random() < 0.5:
                parts.append(
                    _shade(rng, (float(tip[0]), float(tip[1]), float(tip[2]) + 0.16), 0.06)
                )
            else:
                parts.append(ellipsoid(tip + [0, 0, 0.11], (0.015, 0.015, 0.03)))
    if rng.random() < 0.5:  # crystal drops
        for _ in range(int(rng.integers(3, 12))):
            a = rng.uniform(0, 2 * np.pi)
            parts.append(ellipsoid((0.6 * r * np.cos(a), 0.6 * r * np.sin(a), -0.15),
                                   (0.015, 0.015, 0.04)))  # fmt: skip
    return parts


def pendant_lamp(rng: Rng) -> list[Part]:
    cord, r = vary(rng, 0.8, 0.6), vary(rng, 0.22, 0.4)
    parts = [rod((0, 0, 0), (0, 0, cord), 0.005, n=4), box((0, 0, cord), (0.12, 0.12, 0.02))]
    parts.append(_shade(rng, (0, 0, 0), r))
    parts.append(ellipsoid((0, 0, -0.3 * r), (0.05, 0.05, 0.07)))
    if rng.random() < 0.3:  # a row of three
        for sx in (-1, 1):
            x = sx * 3 * r
            parts.append(rod((x, 0, 0), (x, 0, cord), 0.005, n=4))
            parts.append(_shade(rng, (x, 0, 0), r))
        parts.append(box((0, 0, cord), (6 * r + 0.1, 0.08, 0.02)))
    return parts


def street_lamp(rng: Rng) -> list[Part]:
    h, r = vary(rng, 5.0, 0.4), vary(rng, 0.07, 0.3)
    parts = [revolve(np.array([0, h]), np.array([r * 1.4, r]), n=10, top=True)]
    if rng.random() < 0.5:
        parts.append(box((0, 0, 0.3), (4 * r, 4 * r, 0.6)))
    style = int(rng.integers(3))
    if style == 2:  # post-top lantern
        parts.append(box((0, 0, h + 0.25), (0.3, 0.3, 0.5)))
        parts.append(revolve(np.array([h + 0.5, h + 0.75]), np.array([0.3, 0.02]), n=4))
        return parts
    arms = 1 if style == 0 else 2
    reach = vary(rng, 1.2, 0.4)
    for k in range(arms):
        s = 1 if k == 0 else -1
        pts = np.array([[0, 0, h - 0.3], [s * 0.5 * reach, 0, h + 0.1], [s * reach, 0, h]])
        parts += tube(pts, 0.04)
        head = (s * reach, 0, h - 0.05)
        parts.append(box(head, (0.5, 0.22, 0.1)) if rng.random() < 0.5
                     else ellipsoid(head, (0.3, 0.15, 0.08)))  # fmt: skip
    return parts


# --------------------------------------------------------------------------------------
# Racks and fences
# --------------------------------------------------------------------------------------


def shoe_rack(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 0.8, 0.35), vary(rng, 0.3, 0.25), vary(rng, 0.6, 0.4)
    levels = int(rng.integers(2, 5))
    parts = [panel(rng, (sx * w / 2, 0, h / 2), (0.02, d, h)) for sx in (-1, 1)]
    for k in range(levels):
        z = 0.05 + (h - 0.1) * k / max(levels - 1, 1)
        if rng.random() < 0.5:  # a sloping board
            parts.append(quad((0, 0, z), (w / 2, 0, 0), (0, d / 2, 0.04)))
        else:  # two rods
            for y in (-d / 3, d / 3):
                parts.append(rod((-w / 2, y, z + (0.04 if y > 0 else 0)), (w / 2, y, z + (0.04 if y > 0 else 0)),
                                 0.01, n=5))  # fmt: skip
    if rng.random() < 0.4:  # a top with a cushion (a bench)
        parts.append(slab(rng, (0, 0, h + 0.03), w, d, 0.03))
        parts.append(box((0, 0, h + 0.07), (w * 0.95, d * 0.9, 0.06)))
    return parts


def fence(rng: Rng) -> list[Part]:
    length, h = vary(rng, 3.0, 0.4), vary(rng, 1.0, 0.35)
    posts = int(rng.integers(2, 6))
    parts: list[Part] = []
    xs = np.linspace(-length / 2, length / 2, posts)
    for x in xs:
        parts.append(box((x, 0, h / 2 + 0.05), (0.09, 0.09, h + 0.1)))
    rails = int(rng.integers(1, 4))
    for k in range(rails):
        z = h * (0.2 + 0.6 * k / max(rails - 1, 1))
        parts.append(box((0, 0.06, z), (length, 0.03, 0.08)))
    style = int(rng.integers(3))
    if style == 0:  # pickets with points
        n = int(rng.integers(8, 24))
        for x in np.linspace(-length / 2 + 0.1, length / 2 - 0.1, n):
            parts.append(panel(rng, (x, 0.09, 0.45 * h), (0.07, 0.02, 0.9 * h)))
            parts.append(sheet(((x - 0.035, 0.1, 0.9 * h), (x + 0.035, 0.1, 0.9 * h), (x, 0.1, h))))
    elif style == 1:  # boards, one sheet per bay
        for a, b in zip(xs[:-1], xs[1:], strict=True):
            parts.append(quad(((a + b) / 2, 0.08, h / 2), ((b - a) / 2, 0, 0), (0, 0, h / 2)))
    if rng.random() < 0.3:  # a gate: a framed panel with a diagonal
        x = xs[-1] + 0.6
        parts += [box((x, 0, h / 2), (1.0, 0.04, 0.06)), box((x, 0, h), (1.0, 0.04, 0.06)),
                  rod((x - 0.5, 0, 0.05), (x + 0.5, 0, h), 0.02)]  # fmt: skip
    return parts


def gate(rng: Rng) -> list[Part]:
    w, h = vary(rng, 1.2, 0.4), vary(rng, 1.4, 0.35)
    leaves = 1 if rng.random() < 0.6 else 2
    parts = [box((sx * (w / 2 + 0.08), 0, h / 2 + 0.1), (0.14, 0.14, h + 0.2)) for sx in (-1, 1)]
    if rng.random() < 0.5:  # post caps
        parts += [
            ellipsoid((sx * (w / 2 + 0.08), 0, h + 0.25), (0.09, 0.09, 0.09)) for sx in (-1, 1)
        ]
    open_a = rng.uniform(0, 1.2)
    lw = w / leaves
    for k in range(leaves):
        hinge = np.array([-w / 2 if k == 0 else w / 2, 0.0, 0.0])
        s = 1 if k == 0 else -1
        u = s * np.array([np.cos(open_a), np.sin(open_a), 0.0])
        frame = [hinge + [0, 0, 0.1], hinge + lw * u + [0, 0, 0.1], hinge + lw * u + [0, 0, h],
                 hinge + [0, 0, h]]  # fmt: skip
        parts += tube(np.asarray(frame + frame[:1]), 0.025, n=5)
        bars = int(rng.integers(3, 12))
        for t in np.linspace(0.1, 0.9, bars):
            p = hinge + t * lw * u
            parts.append(rod(p + [0, 0, 0.1], p + [0, 0, h * (1.1 if rng.random() < 0.2 else 1.0)],
                             0.012, n=4))  # fmt: skip
        if rng.random() < 0.5:  # a diagonal brace
            parts.append(rod(hinge + [0, 0, 0.1], hinge + lw * u + [0, 0, h], 0.02, n=4))
    if rng.random() < 0.3:  # an arch over the gate
        arc = arc_points(-w / 2 - 0.08, w / 2 + 0.08, 0.3 * w, h + 0.2)
        parts += tube(arc[:, [1, 0, 2]], 0.04, n=5)
    return parts


# --------------------------------------------------------------------------------------
# Aircraft and boats
# --------------------------------------------------------------------------------------


def fighter_jet(rng: Rng) -> list[Part]:
    length, r = vary(rng, 15.0, 0.3), vary(rng, 0.8, 0.3)
    parts = [revolve(np.array([0.0, 0.6, 0.9, 1.0]) * length - length / 2,
                     np.array([r * 0.8, r, r * 0.7, 0.05]), n=10, top=True)]  # fmt: skip
    parts[0] = (parts[0][0][:, [2, 1, 0]], parts[0][1])  # the axis along x
    span, root = length * vary(rng, 0.65, 0.3), length * vary(rng, 0.45, 0.3)
    delta = rng.random() < 0.5
    x0 = -length * 0.35
    tipx = x0 + (0.1 * root if delta else 0.55 * root)
    for sy in (-1, 1):
        tipc = 0.05 * root if delta else 0.2 * root
        parts.append(sheet(((x0, 0, 0), (x0 + root, 0, 0), (tipx + tipc, sy * span / 2, 0),
                            (tipx, sy * span / 2, 0))))  # fmt: skip
    tails = 1 if rng.random() < 0.5 else 2
    for k in range(tails):
        y = 0.0 if tails == 1 else (k - 0.5) * 2 * r
        parts.append(sheet(((-length / 2, y, r), (-length / 2 + 0.2 * length, y, r),
                            (-length / 2 + 0.05 * length, y, r + length * 0.18))))  # fmt: skip
    if not delta:  # tailplanes
        for sy in (-1, 1):
            parts.append(sheet(((-length / 2, 0, 0), (-length / 2 + 0.15 * length, 0, 0),
                                (-length / 2, sy * span * 0.22, 0))))  # fmt: skip
    parts.append(ellipsoid((0.2 * length, 0, 0.8 * r), (0.12 * length, 0.5 * r, 0.4 * r)))  # canopy
    for _ in range(int(rng.integers(0, 5))):  # stores under the wings
        y = rng.uniform(0.2, 0.45) * span * rng.choice([-1, 1])
        parts.append(rod((x0 + 0.5 * root, y, -0.4), (x0 - 0.2 * root, y, -0.4), 0.15, n=6))
    return parts


def airship(rng: Rng) -> list[Part]:
    length = vary(rng, 60.0, 0.3)
    r = length * vary(rng, 0.12, 0.3)
    parts = [ellipsoid((0, 0, 0), (length / 2, r, r))]
    fins = int(rng.choice([3, 4]))
    fl = length * vary(rng, 0.18, 0.3)
    for k in range(fins):
        a = 2 * np.pi * k / fins + (np.pi / 4 if fins == 4 and rng.random() < 0.5 else 0)
        u = np.array([0, np.cos(a), np.sin(a)])
        x = -0.38 * length
        parts.append(sheet(((x, 0, 0) + 0.5 * r * u, (x - fl, 0, 0) + 0.3 * r * u,
                            (x - fl, 0, 0) + 1.3 * r * u, (x - 0.6 * fl, 0, 0) + 1.3 * r * u)))  # fmt: skip
    gl = length * vary(rng, 0.2, 0.4)
    parts.append(box((0.1 * length, 0, -r - 1.0), (gl, 0.2 * gl, 2.5)))
    for _ in range(int(rng.integers(0, 3))):  # engine pods
        y = rng.choice([-1, 1]) * (0.2 * gl + 1.5)
        parts.append(ellipsoid((0.05 * length, y, -r - 0.5), (1.5, 0.6, 0.6)))
    return parts


def quadcopter(rng: Rng) -> list[Part]:
    reach, n = vary(rng, 0.25, 0.35), int(rng.choice([4, 4, 6, 8]))
    body = vary(rng, 0.12, 0.3)
    parts = [box((0, 0, 0), (body, body * vary(rng, 1.0, 0.3), body * 0.4))]
    prop, phase = reach * vary(rng, 0.5, 0.3), rng.uniform(0, np.pi)
    for k in range(n):
        a = 2 * np.pi * (k + 0.5) / n
        tip = np.array([reach * np.cos(a), reach * np.sin(a), 0])
        parts.append(rod((0, 0, 0), tip, 0.01, n=5))
        parts.append(revolve(np.array([-0.01, 0.03]), np.array([0.02, 0.02]), n=8, top=True,
                             c=(float(tip[0]), float(tip[1]))))  # fmt: skip
        b = phase + rng.uniform(0, np.pi)
        u = np.array([np.cos(b), np.sin(b), 0]) * prop / 2
        parts.append(quad(tip + [0, 0, 0.035], u, np.array([-u[1], u[0], 0]) * 0.12))
    if rng.random() < 0.7:  # skids
        for s in (-1, 1):
            parts.append(rod((-body, s * body / 2, -0.12), (body, s * body / 2, -0.12), 0.006, n=4))
            parts.append(rod((0, s * body / 3, -0.02), (0, s * body / 2, -0.12), 0.006, n=4))
    if rng.random() < 0.5:  # camera
        parts.append(ellipsoid((body / 2, 0, -0.05), (0.03, 0.03, 0.03)))
    return parts


def _boat_hull(length: float, w: float, h: float, n: int = 7) -> Part:
    """An open hull along x: U-shaped stations, pointed at both ends (no deck)."""
    xs = np.linspace(-length / 2, length / 2, n)
    half = np.sqrt(np.clip(1 - (2 * xs / length) ** 2, 0.0, 1.0)) * w / 2 + 1e-3
    ring = []
    for x, hw in zip(xs, half, strict=True):
        ring.append([[x, -hw, h], [x, -0.6 * hw, 0.2 * h], [x, 0, 0], [x, 0.6 * hw, 0.2 * h],
                     [x, hw, h]])  # fmt: skip
    v = np.asarray(ring, dtype=float).reshape(-1, 3)
    faces = []
    for i in range(n - 1):
        for j in range(4):
            a, b = i * 5 + j, (i + 1) * 5 + j
            faces += [[a, b, b + 1], [a, b + 1, a + 1]]
    return v, np.asarray(faces, dtype=np.int64)


def rowboat(rng: Rng) -> list[Part]:
    length, w, h = vary(rng, 4.0, 0.3), vary(rng, 1.3, 0.3), vary(rng, 0.5, 0.3)
    parts = [_boat_hull(length, w, h)]
    for k in range(int(rng.integers(1, 4))):  # thwarts
        x = length * (-0.25 + 0.25 * k)
        parts.append(box((x, 0, 0.7 * h), (0.25, w * 0.8, 0.04)))
    if rng.random() < 0.6:  # oars, resting or out
        out = rng.uniform(0, 0.8)
        for s in (-1, 1):
            a = np.array([0.0, s * 0.4 * w, h])
            b = a + 2.5 * np.array([-np.cos(out) * 0.3, s * np.cos(out), -np.sin(out) * 0.5])
            parts.append(rod(a, b, 0.025, n=5))
            parts.append(quad(b, (0.08, 0, 0), 0.25 * (b - a) / np.linalg.norm(b - a)))
    if rng.random() < 0.3:  # outboard motor
        parts.append(box((-length / 2, 0, h), (0.3, 0.25, 0.5)))
        parts.append(rod((-length / 2, 0, h), (-length / 2, 0, -0.3), 0.04, n=5))
    return parts


def catamaran(rng: Rng) -> list[Part]:
    length, gap = vary(rng, 10.0, 0.3), vary(rng, 5.0, 0.3)
    hr = vary(rng, 0.5, 0.3)
    parts: list[Part] = []
    for s in (-1, 1):
        if rng.random() < 0.5:
            parts.append(ellipsoid((0, s * gap / 2, hr), (length / 2, hr, hr)))
        else:
            parts.append(_boat_hull(length, 2 * hr, 2 * hr))
            v, f = parts[-1]
            parts[-1] = (v + [0, s * gap / 2, 0], f)
    dl = length * vary(rng, 0.5, 0.3)
    parts.append(slab(rng, (0, 0, 2 * hr + 0.1), dl, gap, 0.15))
    if rng.random() < 0.6:  # sailing: mast, mainsail, jib
        mh = length * vary(rng, 1.3, 0.3)
        parts.append(rod((0, 0, 2 * hr), (0, 0, 2 * hr + mh), 0.08, n=6))
        parts.append(
            sheet(((0, 0, 2 * hr + 1), (-0.4 * length, 0, 2 * hr + 1), (0, 0, 2 * hr + mh)))
        )
        if rng.random() < 0.7:
            parts.append(sheet(((0.1, 0, 2 * hr + 1), (0.35 * length, 0, 2 * hr + 0.5),
                                (0.1, 0, 2 * hr + 0.8 * mh))))  # fmt: skip
    else:  # a power catamaran's cabin
        parts.append(box((0, 0, 2 * hr + 1.2), (dl * 0.7, gap * 0.8, 2.2)))
        if rng.random() < 0.5:
            parts.append(box((0.05 * length, 0, 2 * hr + 2.8), (dl * 0.4, gap * 0.6, 1.0)))
    return parts


#: Builders of this module by kind name.
BUILDERS = {
    "rocking_chair": rocking_chair, "folding_chair": folding_chair,
    "lounge_chair": lounge_chair, "chandelier": chandelier, "pendant_lamp": pendant_lamp,
    "street_lamp": street_lamp, "shoe_rack": shoe_rack, "fence": fence, "gate": gate,
    "fighter_jet": fighter_jet,
    "airship": airship, "quadcopter": quadcopter, "rowboat": rowboat, "catamaran": catamaran,
}  # fmt: skip
