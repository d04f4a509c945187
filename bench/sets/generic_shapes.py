"""Web-like generic models: man-made and natural kinds built of boxes, sheets and open parts.

Each model is a triangle soup assembled from parts the way web models are built:
closed boxes, zero-thickness quads and discs (table tops, walls, wings, shelves),
open tubes and surfaces of revolution (lamp shades, vases, dishes), capped prisms
and ellipsoids; parts interpenetrate and are never merged, some have their faces
flipped (inconsistent orientation), and most models are not watertight. Within a
kind the proportions, part counts and optional parts vary with the seed; several
kinds share their global statistics on purpose (table / desk / stool, house /
two-story house, chair / stool).

``generic_mesh(kind, seed)`` is deterministic (a seeded numpy generator) and cheap
(milliseconds); :data:`KINDS` lists the kinds. Coordinates: z up, about unit size,
turned by a random angle about z.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from bench.sets.mesh_parts import F, Part, Rng, V, box, ellipsoid, hquad, place, quad, revolve, rod

__all__ = ["KINDS", "generic_mesh"]


def _legs(rng: Rng, w: float, d: float, h: float, t: float, inset: float = 0.0) -> list[Part]:
    """Four box legs of height ``h`` and thickness ``t`` under a ``w`` x ``d`` top."""
    x, y = w / 2 - t / 2 - inset, d / 2 - t / 2 - inset
    return [box((sx * x, sy * y, h / 2), (t, t, h)) for sx in (-1, 1) for sy in (-1, 1)]


def _top(rng: Rng, z: float, w: float, d: float, t: float) -> Part:
    """A top: a box or, half of the time, a zero-thickness sheet."""
    return hquad((0, 0, z), w, d) if rng.random() < 0.5 else box((0, 0, z - t / 2), (w, d, t))


# --------------------------------------------------------------------------------------
# Kinds
# --------------------------------------------------------------------------------------


def chair(rng: Rng) -> list[Part]:
    w, d, h = rng.uniform(0.4, 0.55), rng.uniform(0.4, 0.55), rng.uniform(0.4, 0.48)
    t = rng.uniform(0.03, 0.05)
    parts = _legs(rng, w, d, h, t) + [_top(rng, h + 0.04, w, d, 0.04)]
    bh = rng.uniform(0.35, 0.55)
    if rng.random() < 0.5:
        parts.append(quad((0, -d / 2, h + bh / 2), (w / 2, 0, 0), (0, 0.05 * bh, bh / 2)))
    else:
        parts.append(box((0, -d / 2 + 0.02, h + bh / 2), (w, 0.04, bh)))
    if rng.random() < 0.4:  # armrests
        for sx in (-1, 1):
            parts.append(box((sx * w / 2, 0, h + 0.2), (0.04, d, 0.04)))
            parts.append(box((sx * w / 2, d / 2 - 0.03, h + 0.1), (0.03, 0.03, 0.2)))
    return parts


def table(rng: Rng) -> list[Part]:
    w, d, h = rng.uniform(1.2, 2.0), rng.uniform(0.7, 1.0), rng.uniform(0.7, 0.78)
    t = rng.uniform(0.05, 0.08)
    parts = _legs(rng, w, d, h, t, inset=rng.uniform(0, 0.1)) + [_top(rng, h, w, d, 0.04)]
    if rng.random() < 0.5:  # apron
        parts.append(box((0, d / 2 - 0.08, h - 0.08), (w - 0.2, 0.03, 0.1)))
        parts.append(box((0, -d / 2 + 0.08, h - 0.08), (w - 0.2, 0.03, 0.1)))
    return parts


def desk(rng: Rng) -> list[Part]:
    w, d, h = rng.uniform(1.1, 1.6), rng.uniform(0.55, 0.75), rng.uniform(0.72, 0.78)
    parts = [_top(rng, h, w, d, 0.03)]
    side = quad if rng.random() < 0.5 else None
    for sx in (-1, 1):
        if side is not None:
            parts.append(quad((sx * w / 2, 0, h / 2), (0, d / 2, 0), (0, 0, h / 2)))
        else:
            parts.append(box((sx * (w / 2 - 0.015), 0, h / 2), (0.03, d, h)))
    dw = rng.uniform(0.3, 0.45)  # drawer block
    parts.append(box((w / 2 - dw / 2 - 0.03, 0, h * 0.55), (dw, d * 0.95, h * 0.85)))
    if rng.random() < 0.6:  # modesty panel
        parts.append(quad((0, -d / 2 + 0.05, h * 0.6), (w / 2, 0, 0), (0, 0, h * 0.3)))
    return parts


def stool(rng: Rng) -> list[Part]:
    r, h = rng.uniform(0.15, 0.22), rng.uniform(0.45, 0.75)
    n = int(rng.integers(3, 5))
    parts: list[Part] = []
    if rng.random() < 0.5:
        parts.append(revolve(np.array([h]), np.array([r]), n=16))  # a flat disc
    else:
        parts.append(revolve(np.array([h - 0.04, h]), np.array([r, r]), n=16, top=True))
    for k in range(n):
        a = 2 * np.pi * k / n
        top = (0.7 * r * np.cos(a), 0.7 * r * np.sin(a), h)
        foot = (1.1 * r * np.cos(a), 1.1 * r * np.sin(a), 0.0)
        parts.append(rod(foot, top, rng.uniform(0.015, 0.025), n=6))
    if rng.random() < 0.6:  # foot ring
        z = h * 0.35
        parts.append(revolve(np.array([z, z + 0.02]), np.array([0.95 * r, 0.95 * r]), bottom=False))
    return parts


def bookshelf(rng: Rng) -> list[Part]:
    w, d, h = rng.uniform(0.6, 1.2), rng.uniform(0.25, 0.4), rng.uniform(1.2, 2.0)
    n = int(rng.integers(3, 7))
    parts = (
        [quad((sx * w / 2, 0, h / 2), (0, d / 2, 0), (0, 0, h / 2)) for sx in (-1, 1)]
        if rng.random() < 0.5
        else [box((sx * w / 2, 0, h / 2), (0.03, d, h)) for sx in (-1, 1)]
    )
    for k in range(n + 1):
        parts.append(hquad((0, 0, 0.02 + k * (h - 0.04) / n), w, d))
    if rng.random() < 0.6:
        parts.append(quad((0, -d / 2, h / 2), (w / 2, 0, 0), (0, 0, h / 2)))
    return parts


def bed(rng: Rng) -> list[Part]:
    w, d = rng.uniform(0.9, 1.8), rng.uniform(1.9, 2.1)
    hm = rng.uniform(0.35, 0.5)
    parts = _legs(rng, w, d, 0.15, 0.06) + [box((0, 0, 0.15 + (hm - 0.15) / 2), (w, d, hm - 0.15))]
    hb = rng.uniform(0.8, 1.2)
    parts.append(box((0, -d / 2, hb / 2), (w + 0.05, 0.05, hb)))
    if rng.random() < 0.5:
        parts.append(quad((0, d / 2, hm / 2 + 0.1), (w / 2, 0, 0), (0, 0, hm / 2 + 0.1)))
    if rng.random() < 0.6:  # pillow
        parts.append(ellipsoid((0, -d / 2 + 0.25, hm + 0.05), (0.3 * w, 0.15, 0.06)))
    return parts


def lamp(rng: Rng) -> list[Part]:
    h, rb = rng.uniform(0.5, 1.6), rng.uniform(0.1, 0.2)
    parts = [revolve(np.array([0.0, 0.03]), np.array([rb, rb * 0.9]), top=True)]
    parts.append(rod((0, 0, 0.03), (0, 0, h), rng.uniform(0.01, 0.02)))
    rs = rng.uniform(0.12, 0.3)
    hs = rng.uniform(0.15, 0.3)
    parts.append(revolve(np.array([h - 0.5 * hs, h + 0.5 * hs]), np.array([rs, rs * 0.6]),
                         bottom=False))  # fmt: skip
    return parts


def staircase(rng: Rng) -> list[Part]:
    n, w = int(rng.integers(5, 14)), rng.uniform(0.8, 1.5)
    rise, run = rng.uniform(0.15, 0.2), rng.uniform(0.25, 0.32)
    parts = []
    for k in range(n):
        if rng.random() < 0.5:
            parts.append(box((0, k * run, (k + 0.5) * rise), (w, run, rise)))
        else:  # tread and riser sheets
            parts.append(hquad((0, k * run, (k + 1) * rise), w, run))
            parts.append(
                quad((0, (k - 0.5) * run, (k + 0.5) * rise), (w / 2, 0, 0), (0, 0, rise / 2))
            )
    if rng.random() < 0.6:
        x = w / 2
        parts.append(rod((x, 0, rise + 0.9), (x, (n - 1) * run, n * rise + 0.9), 0.025))
        for k in range(0, n, 3):
            parts.append(
                rod((x, k * run, (k + 1) * rise), (x, k * run, (k + 1) * rise + 0.9), 0.02)
            )
    return parts


def _walls(w: float, d: float, z0: float, h: float, sheet: bool) -> list[Part]:
    if not sheet:
        return [box((0, 0, z0 + h / 2), (w, d, h))]
    return [quad((0, sy * d / 2, z0 + h / 2), (w / 2, 0, 0), (0, 0, h / 2)) for sy in (-1, 1)] + [
        quad((sx * w / 2, 0, z0 + h / 2), (0, d / 2, 0), (0, 0, h / 2)) for sx in (-1, 1)
    ]


def _roof(w: float, d: float, z: float, rh: float) -> list[Part]:
    over = 0.1
    parts = []
    for sy in (-1, 1):
        c = (0, sy * (d / 4 + over / 2), z + rh / 2)
        parts.append(quad(c, (w / 2 + over, 0, 0), (0, sy * (d / 2 + over) / 2, -rh / 2)))
    gable = np.array([[-w / 2, -d / 2, z], [-w / 2, d / 2, z], [-w / 2, 0, z + rh]])
    parts.append((gable, np.array([[0, 1, 2]])))
    parts.append((gable * [-1, 1, 1], np.array([[0, 2, 1]])))
    return parts


def house(rng: Rng) -> list[Part]:
    w, d, h = rng.uniform(1.0, 1.6), rng.uniform(0.8, 1.2), rng.uniform(0.5, 0.7)
    parts = _walls(w, d, 0, h, rng.random() < 0.6) + _roof(w, d, h, rng.uniform(0.3, 0.5))
    if rng.random() < 0.6:  # chimney
        parts.append(box((w / 4, d / 4, h + 0.35), (0.1, 0.1, 0.4)))
    parts.append(quad((0, -d / 2 - 0.005, 0.2), (0.1, 0, 0), (0, 0, 0.2)))  # door
    return parts


def two_story_house(rng: Rng) -> list[Part]:
    w, d, h = rng.uniform(1.0, 1.5), rng.uniform(0.8, 1.1), rng.uniform(0.45, 0.6)
    sheet = rng.random() < 0.6
    parts = (
        _walls(w, d, 0, h, sheet) + _walls(w, d, h, h, sheet) + [hquad((0, 0, h), w + 0.1, d + 0.1)]
    )
    parts += _roof(w, d, 2 * h, rng.uniform(0.3, 0.5))
    if rng.random() < 0.5:  # balcony
        parts.append(box((0, -d / 2 - 0.15, h), (w * 0.5, 0.3, 0.04)))
    return parts


def skyscraper(rng: Rng) -> list[Part]:
    w, h = rng.uniform(0.25, 0.45), rng.uniform(2.0, 3.5)
    levels = int(rng.integers(1, 4))
    parts, z = [], 0.0
    for k in range(levels):
        lh = h * (0.6 if k == 0 else 0.4 / (levels - 1 + 1e-9)) if levels > 1 else h
        s = w * (1 - 0.2 * k)
        parts += _walls(s, s * rng.uniform(0.7, 1.0), z, lh, rng.random() < 0.5)
        parts.append(hquad((0, 0, z + lh), s, s))
        z += lh
    if rng.random() < 0.6:
        parts.append(rod((0, 0, z), (0, 0, z + rng.uniform(0.2, 0.5)), 0.01))
    return parts


def _wheel_parts(c: tuple[float, float, float], r: float, width: float, axis: int) -> list[Part]:
    v, f = revolve(np.array([-width / 2, width / 2]), np.array([r, r]), n=12, bottom=True, top=True)
    a = np.eye(3)[axis]
    return [(place(v, np.asarray(c, float), a), f)]


def car(rng: Rng) -> list[Part]:
    length, w, h = rng.uniform(1.6, 2.2), rng.uniform(0.7, 0.9), rng.uniform(0.3, 0.4)
    r = rng.uniform(0.14, 0.2)
    parts = [box((0, 0, r + h / 2 - 0.05), (length, w, h))]
    cl = length * rng.uniform(0.4, 0.6)
    parts.append(box((-0.1 * length, 0, r + h + 0.1), (cl, w * 0.9, 0.3)))
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts += _wheel_parts((sx * length * 0.32, sy * w / 2, r), r, 0.12, 1)
    return parts


def airplane(rng: Rng) -> list[Part]:
    length, r = rng.uniform(2.0, 3.0), rng.uniform(0.12, 0.2)
    parts = [ellipsoid((0, 0, 0), (length / 2, r, r))]
    span, chord = rng.uniform(1.8, 3.0), rng.uniform(0.3, 0.5)
    sweep = rng.uniform(0.0, 0.3)
    for sy in (-1, 1):  # wings: sheets
        tip = np.array([-sweep, sy * span / 2, 0])
        v = np.array(
            [
                [chord / 2, 0, 0],
                [-chord / 2, 0, 0],
                tip + [-chord / 4, 0, 0],
                tip + [chord / 4, 0, 0],
            ]
        )
        parts.append((v, np.array([[0, 1, 2], [0, 2, 3]])))
    tail = -length / 2 + 0.1
    parts.append(quad((tail, 0, r + 0.15), (0.12, 0, 0), (0, 0, 0.17)))  # fin
    parts.append(hquad((tail, 0, 0), 0.25, span * rng.uniform(0.25, 0.4)))
    if rng.random() < 0.5:  # engines
        for sy in (-1, 1):
            parts.append(rod((0.15, sy * span / 4, -0.1), (-0.15, sy * span / 4, -0.1), 0.06))
    return parts


def ship(rng: Rng) -> list[Part]:
    length, w, h = rng.uniform(2.0, 3.0), rng.uniform(0.4, 0.6), rng.uniform(0.2, 0.35)
    bow = np.array([length / 2 + 0.3, 0, h])
    v = np.array([
        [-length / 2, -w / 2, h], [length / 2, -w / 2, h], bow, [length / 2, w / 2, h],
        [-length / 2, w / 2, h], [-length / 2, -w / 3, 0], [length / 2, -w / 3, 0],
        [length / 2, w / 3, 0], [-length / 2, w / 3, 0],
    ])  # fmt: skip
    f = np.array([[5, 6, 1], [5, 1, 0], [6, 2, 1], [6, 7, 2], [7, 3, 2], [7, 8, 4], [7, 4, 3],
                  [8, 5, 0], [8, 0, 4], [5, 8, 7], [5, 7, 6]])  # open deck  # fmt: skip
    parts: list[Part] = [(v, f), hquad((0.1, 0, h), length, w)]
    for k in range(int(rng.integers(1, 4))):
        parts.append(box((-0.2 * k - 0.2, 0, h + 0.12 + 0.05 * k), (0.4, w * 0.6, 0.25 + 0.1 * k)))
    if rng.random() < 0.7:
        parts.append(rod((0.3, 0, h), (0.3, 0, h + rng.uniform(0.6, 1.0)), 0.02))
    return parts


def bicycle(rng: Rng) -> list[Part]:
    r, base = rng.uniform(0.3, 0.36), rng.uniform(0.95, 1.1)
    parts: list[Part] = []
    for x in (-base / 2, base / 2):
        v, f = revolve(np.array([-0.02, 0.02]), np.array([r, r]), n=24, bottom=False)
        parts.append((place(v, np.array([x, 0, r]), np.array([0, 1.0, 0])), f))
    seat = np.array([-0.15, 0, r + 0.5])
    head = np.array([base / 2 - 0.15, 0, r + 0.45])
    crank = np.array([0.0, 0, r])
    for a, b in ((-base / 2, crank), (crank, seat), (seat, head), (head, crank)):
        parts.append(rod(np.array([a, 0, r]) if np.isscalar(a) else a, b, 0.02, n=6))
    parts.append(rod((base / 2, 0, r), head, 0.02, n=6))
    parts.append(rod(head + [0, -0.25, 0.1], head + [0, 0.25, 0.1], 0.015, n=6))
    parts.append(box(seat + [0, 0, 0.03], (0.2, 0.08, 0.04)))
    return parts


def wheel(rng: Rng) -> list[Part]:
    r, wd = rng.uniform(0.4, 0.6), rng.uniform(0.1, 0.3)
    parts = [revolve(np.array([-wd / 2, wd / 2]), np.array([r, r]), n=24, bottom=False)]
    parts.append(
        revolve(np.array([-wd / 2, wd / 2]), np.array([0.8 * r, 0.8 * r]), n=24, bottom=False)
    )
    parts.append(revolve(np.array([-wd / 2 - 0.02, wd / 2 + 0.02]), np.array([0.15 * r, 0.15 * r]),
                         top=True))  # fmt: skip
    n = int(rng.integers(4, 9))
    for k in range(n):
        a = 2 * np.pi * k / n
        parts.append(rod((0.15 * r * np.cos(a), 0.15 * r * np.sin(a), 0),
                         (0.8 * r * np.cos(a), 0.8 * r * np.sin(a), 0), 0.03 * r, n=6))  # fmt: skip
    return [(place(v, np.zeros(3), np.array([1.0, 0, 0])), f) for v, f in parts]


def satellite_dish(rng: Rng) -> list[Part]:
    R, depth = rng.uniform(0.5, 0.9), rng.uniform(0.1, 0.3)
    rr = np.linspace(0.0, R, 6)
    v, f = revolve(depth * (rr / R) ** 2, rr + 1e-3, n=20, bottom=False)
    tilt = rng.uniform(0.3, 0.8)
    h = rng.uniform(0.6, 1.2)
    axis = np.array([np.sin(tilt), 0, np.cos(tilt)])
    parts = [(place(v, np.array([0, 0, h]), axis), f)]
    parts.append(rod((0, 0, 0), (0, 0, h), 0.03))
    parts.append(rod((0, 0, h), np.array([0, 0, h]) + 0.7 * R * axis, 0.01))
    parts.append(box((0, 0, 0.02), (0.4, 0.4, 0.04)))
    return parts


def sink(rng: Rng) -> list[Part]:
    w, d, h = rng.uniform(0.5, 0.8), rng.uniform(0.4, 0.55), rng.uniform(0.15, 0.25)
    z = rng.uniform(0.75, 0.9)
    basin = (
        [hquad((0, 0, z - h), w, d)]
        + [quad((sx * w / 2, 0, z - h / 2), (0, d / 2, 0), (0, 0, h / 2)) for sx in (-1, 1)]
        + [quad((0, sy * d / 2, z - h / 2), (w / 2, 0, 0), (0, 0, h / 2)) for sy in (-1, 1)]
    )
    parts = basin + [box((0, -d / 2 - 0.05, z), (w + 0.2, 0.12, 0.04))]
    parts.append(rod((0, -d / 2 - 0.05, z), (0, -d / 2 - 0.05, z + 0.25), 0.015))
    parts.append(rod((0, -d / 2 - 0.05, z + 0.25), (0, -d / 2 + 0.1, z + 0.25), 0.015))
    if rng.random() < 0.5:  # pedestal
        parts.append(rod((0, 0, 0), (0, 0, z - h), rng.uniform(0.06, 0.1)))
    else:  # cabinet
        parts.append(box((0, 0, (z - h) / 2), (w + 0.1, d + 0.1, z - h)))
    return parts


def door(rng: Rng) -> list[Part]:
    w, h = rng.uniform(0.7, 1.0), rng.uniform(1.9, 2.2)
    parts = [box((0, 0, h / 2), (w, 0.04, h)) if rng.random() < 0.5
             else quad((0, 0, h / 2), (w / 2, 0, 0), (0, 0, h / 2))]  # fmt: skip
    for sx in (-1, 1):
        parts.append(box((sx * (w / 2 + 0.04), 0, h / 2 + 0.02), (0.08, 0.12, h + 0.04)))
    parts.append(box((0, 0, h + 0.06), (w + 0.16, 0.12, 0.08)))
    parts.append(rod((w / 2 - 0.1, -0.1, h * 0.48), (w / 2 - 0.1, 0.1, h * 0.48), 0.015))
    return parts


def monitor(rng: Rng) -> list[Part]:
    w, h = rng.uniform(0.5, 0.8), rng.uniform(0.3, 0.5)
    z = rng.uniform(0.12, 0.25)
    parts = [box((0, 0, z + h / 2), (w, rng.uniform(0.02, 0.06), h))]
    if rng.random() < 0.5:
        parts.append(quad((0, -0.04, z + h / 2), (w / 2 - 0.02, 0, 0), (0, 0, h / 2 - 0.02)))
    parts.append(box((0, 0.04, z / 2 + 0.05), (0.06, 0.03, z + 0.1)))
    parts.append(box((0, 0.04, 0.01), (rng.uniform(0.2, 0.3), 0.18, 0.02)))
    return parts


def guitar(rng: Rng) -> list[Part]:
    lb, ub = rng.uniform(0.18, 0.22), rng.uniform(0.13, 0.17)
    t = rng.uniform(0.04, 0.1)
    parts = [ellipsoid((0, 0, 0), (lb, t, lb * 1.1)), ellipsoid((0, 0, 0.28), (ub, t, ub))]
    nl = rng.uniform(0.45, 0.6)
    parts.append(box((0, 0, 0.3 + nl / 2), (0.05, 0.03, nl)))
    parts.append(box((0, 0, 0.35 + nl), (0.08, 0.02, 0.16)))
    return parts


def bottle(rng: Rng) -> list[Part]:
    h, r = rng.uniform(0.6, 1.2), rng.uniform(0.12, 0.25)
    neck = rng.uniform(0.2, 0.45)
    z = np.array([0, 0.05, 0.6, 0.75, 0.9, 1.0]) * h
    rr = r * np.array([0.9, 1.0, 1.0, 0.6 + 0.3 * rng.random(), neck, neck])
    return [revolve(z, rr, n=16, bottom=True, top=False)]


def tree(rng: Rng) -> list[Part]:
    h = rng.uniform(1.0, 2.0)
    parts = [revolve(np.array([0, 0.5 * h]), np.array([0.06, 0.04]) * h, n=8, top=True)]
    if rng.random() < 0.5:  # conifer: stacked cones
        for k in range(int(rng.integers(2, 4))):
            z0 = 0.35 * h + 0.2 * h * k
            parts.append(
                revolve(
                    np.array([z0, z0 + 0.45 * h]), np.array([0.35 * h * (1 - 0.25 * k), 0.01]), n=12
                )
            )
    else:
        for _ in range(int(rng.integers(1, 4))):
            c = (rng.normal(0, 0.08 * h), rng.normal(0, 0.08 * h), h * rng.uniform(0.65, 0.8))
            parts.append(ellipsoid(c, h * rng.uniform(0.2, 0.32, size=3)))
    return parts


def quadruped(rng: Rng) -> list[Part]:
    length, hgt = rng.uniform(0.8, 1.4), rng.uniform(0.4, 0.8)
    body_r = rng.uniform(0.14, 0.22)
    parts = [ellipsoid((0, 0, hgt + body_r * 0.5), (length / 2, body_r, body_r))]
    for sx in (-1, 1):
        for sy in (-1, 1):
            x = sx * (length / 2 - 0.12)
            foot = (x + rng.normal(0, 0.06), sy * body_r * 0.6, 0.0)
            parts.append(rod(foot, (x, sy * body_r * 0.6, hgt + 0.1), rng.uniform(0.03, 0.05), n=6))
    neck_top = np.array([length / 2 + 0.15, 0, hgt + body_r + rng.uniform(0.1, 0.4)])
    parts.append(rod((length / 2 - 0.1, 0, hgt + body_r * 0.6), neck_top, 0.05, n=6))
    parts.append(ellipsoid(neck_top + [0.08, 0, 0], (0.14, 0.07, 0.07)))
    parts.append(rod((-length / 2, 0, hgt + body_r * 0.8), (-length / 2 - 0.3, 0, hgt + rng.uniform(-0.2, 0.3)),
                     0.02, n=6))  # fmt: skip
    return parts


def human(rng: Rng) -> list[Part]:
    h = rng.uniform(1.5, 1.9)
    leg, sh = 0.47 * h, 0.12 * h
    parts = [box((0, 0, leg + 0.15 * h), (2 * sh, 0.1 * h, 0.3 * h)) if rng.random() < 0.5
             else ellipsoid((0, 0, leg + 0.15 * h), (sh, 0.06 * h, 0.17 * h))]  # fmt: skip
    parts.append(ellipsoid((0, 0, 0.92 * h), (0.06 * h, 0.07 * h, 0.08 * h)))
    for s in (-1, 1):
        sw = rng.uniform(-0.25, 0.25)
        parts.append(
            rod((s * 0.06 * h, sw * leg, 0), (s * 0.06 * h, 0, leg + 0.02), 0.035 * h, n=6)
        )
        a = rng.uniform(0.1, 1.2)
        hand = np.array(
            [
                s * (sh + 0.38 * h * np.sin(a)),
                rng.uniform(-0.1, 0.1),
                leg + 0.28 * h - 0.38 * h * np.cos(a),
            ]
        )
        parts.append(rod((s * sh, 0, leg + 0.28 * h), hand, 0.025 * h, n=6))
    return parts


def fish(rng: Rng) -> list[Part]:
    length = rng.uniform(0.8, 1.4)
    hgt, wd = length * rng.uniform(0.15, 0.35), length * rng.uniform(0.08, 0.15)
    parts = [ellipsoid((0, 0, 0), (length / 2, wd, hgt))]
    tx = -length / 2
    ts = rng.uniform(0.15, 0.3) * length
    parts.append(
        (np.array([[tx + 0.05, 0, 0], [tx - ts, 0, ts], [tx - ts, 0, -ts]]), np.array([[0, 1, 2]]))
    )
    parts.append(
        (
            np.array([[0.1, 0, hgt * 0.9], [-0.2, 0, hgt * 0.9], [-0.15, 0, hgt + 0.12]]),
            np.array([[0, 1, 2]]),
        )
    )
    for s in (-1, 1):
        parts.append((np.array([[0.15, s * wd, -0.3 * hgt], [0.05, s * wd, -0.3 * hgt],
                                [0.0, s * (wd + 0.12), -0.5 * hgt]]), np.array([[0, 1, 2]])))  # fmt: skip
    return parts


#: Builders by kind name.
_BUILDERS: dict[str, Callable[[Rng], list[Part]]] = {
    "chair": chair, "table": table, "desk": desk, "stool": stool, "bookshelf": bookshelf,
    "bed": bed, "lamp": lamp, "staircase": staircase, "house": house,
    "two_story_house": two_story_house, "skyscraper": skyscraper, "car": car,
    "airplane": airplane, "ship": ship, "bicycle": bicycle, "wheel": wheel,
    "satellite_dish": satellite_dish, "sink": sink, "door": door, "monitor": monitor,
    "guitar": guitar, "bottle": bottle, "tree": tree, "quadruped": quadruped,
    "human": human, "fish": fish,
}  # fmt: skip
#: The kinds, in a fixed order.
KINDS: tuple[str, ...] = tuple(_BUILDERS)


def generic_mesh(kind: str, seed: int) -> tuple[V, F]:
    """Vertices (v, 3) and faces (f, 3) of one generated model.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    seed : int
        Model number; the same ``(kind, seed)`` always gives the same arrays.

    Raises
    ------
    ValueError
        For an unknown kind.
    """
    import zlib

    if kind not in _BUILDERS:
        raise ValueError(f"unknown generic kind {kind!r}: choose from {KINDS}")
    rng = np.random.default_rng(zlib.crc32(f"generic/{kind}/{seed}".encode()))
    parts = _BUILDERS[kind](rng)
    vs, fs, at = [], [], 0
    for v, f in parts:
        f = np.asarray(f, dtype=np.int64)
        if rng.random() < 0.3:  # inconsistent orientation
            f = f[:, ::-1]
        vs.append(np.asarray(v, dtype=np.float64))
        fs.append(f + at)
        at += len(v)
    v = np.concatenate(vs)
    a = rng.uniform(0, 2 * np.pi)
    rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    return v @ rot.T, np.concatenate(fs)
