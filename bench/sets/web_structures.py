"""Builders of the ``web`` set's buildings and vehicles (see :mod:`bench.sets.web_shapes`).

Each builder takes a seeded generator and returns the parts of one model, z up,
standing on z = 0, in metres (scaled down: a house is about 10 m, but only the
proportions matter). Close families: five buildings, four road and rail vehicles,
four aircraft, three boats. Proportions vary by up to about 40 % within a kind,
parts are optional, walls are boxes or open sheets.
"""

from __future__ import annotations

import numpy as np

from bench.sets.mesh_parts import (
    Part,
    Rng,
    box,
    ellipsoid,
    hquad,
    place,
    prism,
    quad,
    revolve,
    rod,
    sheet,
    transform,
)
from bench.sets.web_furniture import cylinder, vary

__all__ = ["walls", "roof", "wheel", "BUILDERS"]


def walls(rng: Rng, w: float, d: float, z0: float, h: float) -> list[Part]:
    """A storey: a closed box or, 60 % of the time, four open wall sheets."""
    if rng.random() < 0.4:
        return [box((0, 0, z0 + h / 2), (w, d, h))]
    return [quad((0, sy * d / 2, z0 + h / 2), (w / 2, 0, 0), (0, 0, h / 2)) for sy in (-1, 1)] + [
        quad((sx * w / 2, 0, z0 + h / 2), (0, d / 2, 0), (0, 0, h / 2)) for sx in (-1, 1)
    ]


def roof(rng: Rng, w: float, d: float, z: float, rh: float) -> list[Part]:
    """A gable roof (two sheets and gable triangles), a hip roof, or a flat one with a parapet."""
    style = int(rng.integers(3))
    over = 0.1 * rng.random()
    if style == 0:
        parts = [quad((0, sy * (d / 4 + over / 2), z + rh / 2), (w / 2 + over, 0, 0),
                      (0, sy * (d / 2 + over) / 2, -rh / 2)) for sy in (-1, 1)]  # fmt: skip
        for sx in (-1, 1):
            parts.append(
                sheet(((sx * w / 2, -d / 2, z), (sx * w / 2, d / 2, z), (sx * w / 2, 0, z + rh)))
            )
        return parts
    if style == 1:
        r = min(w, d) / 2
        v = np.array([[-w / 2, -d / 2, z], [w / 2, -d / 2, z], [w / 2, d / 2, z], [-w / 2, d / 2, z],
                      [-w / 2 + r, 0, z + rh], [w / 2 - r, 0, z + rh]])  # fmt: skip
        f = np.array([[0, 1, 5], [0, 5, 4], [2, 3, 4], [2, 4, 5], [1, 2, 5], [3, 0, 4]])
        return [(v, f)]
    return [hquad((0, 0, z), w, d), box((0, 0, z + 0.1), (w + 0.05, d + 0.05, 0.2))]


def wheel(c: tuple[float, float, float] | np.ndarray, r: float, width: float) -> Part:
    """A closed wheel of radius ``r`` whose axle is along y, centred at ``c``."""
    v, f = revolve(np.array([-width / 2, width / 2]), np.array([r, r]), n=12, top=True)
    return place(v, np.asarray(c, float), np.array([0.0, 1.0, 0.0])), f


# --------------------------------------------------------------------------------------
# Buildings
# --------------------------------------------------------------------------------------


def _windows(rng: Rng, w: float, y: float, z: float, n: int) -> list[Part]:
    """``n`` window sheets on the wall y = ``y`` at height ``z``."""
    xs = np.linspace(-w / 2 + w / (2 * n), w / 2 - w / (2 * n), n)
    return [quad((x, y * 1.01, z), (0.35 * w / n, 0, 0), (0, 0, 0.12)) for x in xs]


def house(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 1.3, 0.3), vary(rng, 1.0, 0.3), vary(rng, 0.6, 0.25)
    parts = walls(rng, w, d, 0, h) + roof(rng, w, d, h, vary(rng, 0.4, 0.4))
    if rng.random() < 0.6:
        parts.append(box((w / 4, d / 4, h + 0.35), (0.1, 0.1, 0.45)))
    parts.append(quad((0, -d / 2 - 0.005, 0.2), (0.1, 0, 0), (0, 0, 0.2)))
    if rng.random() < 0.6:
        parts += _windows(rng, w, -d / 2, 0.35, int(rng.integers(2, 4)))
    if rng.random() < 0.3:  # porch
        parts.append(hquad((0, -d / 2 - 0.2, 0.05), 0.6 * w, 0.4))
    return parts


def two_story_home(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 1.3, 0.3), vary(rng, 0.95, 0.25), vary(rng, 0.5, 0.2)
    parts = walls(rng, w, d, 0, h) + walls(rng, w, d, h, h) + [hquad((0, 0, h), w + 0.1, d + 0.1)]
    parts += roof(rng, w, d, 2 * h, vary(rng, 0.4, 0.4))
    for z in (0.3 * h, 1.3 * h):
        if rng.random() < 0.6:
            parts += _windows(rng, w, -d / 2, z, int(rng.integers(2, 5)))
    if rng.random() < 0.5:  # balcony
        parts.append(box((0, -d / 2 - 0.15, h), (w * 0.5, 0.3, 0.04)))
    if rng.random() < 0.4:  # garage
        gw = vary(rng, 0.5, 0.3)
        garage = walls(rng, gw, 0.8 * d, 0, 0.7 * h) + [hquad((0, 0, 0.7 * h), gw, 0.8 * d)]
        parts += [transform(part, shift=(w / 2 + gw / 2, 0, 0)) for part in garage]
    return parts


def skyscraper(rng: Rng) -> list[Part]:
    w, h = vary(rng, 0.35, 0.3), vary(rng, 2.8, 0.35)
    levels = int(rng.integers(1, 4))
    parts: list[Part] = []
    z = 0.0
    round_ = rng.random() < 0.2
    for k in range(levels):
        lh = h / levels * (1.5 if k == 0 and levels > 1 else 1.0)
        s = w * (1 - 0.18 * k)
        if round_:
            parts.append(cylinder((0, 0, z), s / 2, lh, n=16, top=False))
        else:
            parts += walls(rng, s, s * rng.uniform(0.7, 1.0), z, lh)
        parts.append(hquad((0, 0, z + lh), s, s))
        z += lh
    if rng.random() < 0.6:
        parts.append(rod((0, 0, z), (0, 0, z + vary(rng, 0.35, 0.4)), 0.01))
    if rng.random() < 0.3:  # podium
        parts.append(box((0, 0, 0.1), (2.2 * w, 1.8 * w, 0.2)))
    return parts


def church(rng: Rng) -> list[Part]:
    w, length, h = vary(rng, 0.8, 0.25), vary(rng, 1.8, 0.3), vary(rng, 0.7, 0.25)
    parts = walls(rng, length, w, 0, h) + roof(rng, length, w, h, vary(rng, 0.45, 0.3))
    ts, th = vary(rng, 0.35, 0.25), vary(rng, 1.6, 0.3)
    tx = -length / 2 - ts / 2 if rng.random() < 0.7 else 0.0
    parts.append(box((tx, 0, th / 2), (ts, ts, th)))
    sh = vary(rng, 0.7, 0.4)
    parts.append(revolve(np.array([th, th + sh]), np.array([ts * 0.7, 0.01]), n=4, c=(tx, 0)))
    if rng.random() < 0.6:  # apse
        parts.append(revolve(np.array([0, 0.8 * h]), np.array([w * 0.4, w * 0.4]), n=12,
                             top=True, c=(length / 2, 0)))  # fmt: skip
    if rng.random() < 0.4:  # cross
        parts.append(rod((tx, 0, th + sh), (tx, 0, th + sh + 0.15), 0.01, n=4))
    return parts


def tower(rng: Rng) -> list[Part]:
    r, h = vary(rng, 0.3, 0.3), vary(rng, 2.0, 0.35)
    parts: list[Part] = []
    if rng.random() < 0.5:  # round, tapering (lighthouse, castle tower)
        parts.append(revolve(np.array([0, h]), np.array([r, r * rng.uniform(0.6, 1.0)]), n=16))
    else:
        parts += walls(rng, 2 * r, 2 * r, 0, h)
    top = int(rng.integers(3))
    if top == 0:  # battlements
        for k in range(8):
            a = 2 * np.pi * k / 8
            parts.append(
                box((0.9 * r * np.cos(a), 0.9 * r * np.sin(a), h + 0.06), (0.08, 0.08, 0.12))
            )
    elif top == 1:  # conical roof
        parts.append(
            revolve(np.array([h, h + vary(rng, 0.6, 0.4)]), np.array([1.1 * r, 0.01]), n=12)
        )
    else:  # lantern room
        parts.append(cylinder((0, 0, h), 0.7 * r, 0.25, n=12))
        parts.append(revolve(np.array([h + 0.25, h + 0.4]), np.array([0.8 * r, 0.05]), n=12))
    if rng.random() < 0.3:
        parts.append(cylinder((0, 0, 0), 1.8 * r, 0.15, n=16))
    return parts


# --------------------------------------------------------------------------------------
# Road and rail vehicles
# --------------------------------------------------------------------------------------


def _axles(rng: Rng, xs: list[float], w: float, r: float) -> list[Part]:
    return [wheel((x, sy * w / 2, r), r, 0.1 + 0.1 * r) for x in xs for sy in (-1, 1)]


def car(rng: Rng) -> list[Part]:
    length, w, h = vary(rng, 2.0, 0.25), vary(rng, 0.85, 0.15), vary(rng, 0.35, 0.25)
    r = vary(rng, 0.16, 0.2)
    parts = [box((0, 0, r + h / 2 - 0.05), (length, w, h))]
    cl, ch = length * rng.uniform(0.35, 0.6), vary(rng, 0.3, 0.3)
    x0 = -length * rng.uniform(0.0, 0.15)
    outline = np.array([[x0 - cl / 2, 0], [x0 + cl / 2, 0], [x0 + cl / 2 - 0.25 * cl, ch],
                        [x0 - cl / 2 + 0.1 * cl, ch]])  # fmt: skip
    cabin = prism(outline, -0.45 * w, 0.45 * w, caps=rng.random() < 0.5)
    parts.append((cabin[0] + [0, 0, r + h - 0.06], cabin[1]))
    parts += _axles(rng, [-0.32 * length, 0.32 * length], w, r)
    if rng.random() < 0.3:  # spoiler
        parts.append(hquad((-length / 2, 0, r + h + 0.08), 0.15, w))
    return parts


def truck(rng: Rng) -> list[Part]:
    length, w, r = vary(rng, 3.0, 0.3), vary(rng, 1.0, 0.15), vary(rng, 0.22, 0.2)
    cab_l, cab_h = vary(rng, 0.7, 0.25), vary(rng, 0.9, 0.25)
    parts = [box((length / 2 - cab_l / 2, 0, r + cab_h / 2), (cab_l, w, cab_h))]
    bed_l = length - cab_l - 0.05
    if rng.random() < 0.6:  # box body
        body = walls(rng, bed_l, w, r + 0.15, vary(rng, 1.1, 0.3))
    else:  # open bed
        body = [hquad((0, 0, r + 0.15), bed_l, w)]
        body += [quad((0, sy * w / 2, r + 0.3), (bed_l / 2, 0, 0), (0, 0, 0.15)) for sy in (-1, 1)]
    parts += [transform(part, shift=(-length / 2 + bed_l / 2, 0, 0)) for part in body]
    parts.append(box((0, 0, r + 0.08), (length, 0.5 * w, 0.1)))  # chassis
    xs = [length / 2 - cab_l / 2, -length / 2 + 0.4]
    if rng.random() < 0.6:
        xs.append(-length / 2 + 0.4 + 2.2 * r)
    parts += _axles(rng, xs, w, r)
    return parts


def bus(rng: Rng) -> list[Part]:
    length, w, h = vary(rng, 4.0, 0.3), vary(rng, 1.0, 0.1), vary(rng, 1.1, 0.25)
    r = vary(rng, 0.2, 0.2)
    parts = walls(rng, length, w, r, h) + [hquad((0, 0, r + h), length, w)]
    parts.append(hquad((0, 0, r), length, w))
    for sy in (-1, 1):
        if rng.random() < 0.7:
            parts += _windows(rng, length, sy * w / 2, r + 0.7 * h, int(rng.integers(4, 9)))
    if rng.random() < 0.25:  # double decker
        parts += walls(rng, length, w, r + h, 0.8 * h) + [hquad((0, 0, r + 1.8 * h), length, w)]
    xs = [0.35 * length, -0.3 * length] + ([-0.3 * length - 2.4 * r] if rng.random() < 0.3 else [])
    return parts + _axles(rng, xs, w, r)


def train_car(rng: Rng) -> list[Part]:
    length, w, h = vary(rng, 5.0, 0.3), vary(rng, 0.9, 0.1), vary(rng, 1.0, 0.2)
    r = vary(rng, 0.12, 0.2)
    z0 = 2 * r + 0.1
    t = np.linspace(0, np.pi, 9)
    arc = np.column_stack([np.cos(t) * w / 2, h + np.sin(t) * vary(rng, 0.15, 0.5)])
    outline = np.vstack([[[w / 2, 0]], arc, [[-w / 2, 0]]])
    body = prism(outline, -length / 2, length / 2, caps=rng.random() < 0.6)  # along y, then turn
    v = body[0][:, [1, 0, 2]] + [0, 0, z0]
    parts = [(v, body[1])]
    for bx in (-0.35 * length, 0.35 * length):  # bogies
        parts.append(box((bx, 0, r + 0.05), (4 * r, 0.8 * w, 0.08)))
        parts += _axles(rng, [bx - r * 1.2, bx + r * 1.2], 0.8 * w, r)
    for sx in (-1, 1):  # couplers
        parts.append(box((sx * (length / 2 + 0.1), 0, z0 + 0.15), (0.2, 0.1, 0.1)))
    if rng.random() < 0.5:
        parts += _windows(rng, length, w / 2, z0 + 0.6 * h, int(rng.integers(5, 12)))
    return parts


# --------------------------------------------------------------------------------------
# Aircraft
# --------------------------------------------------------------------------------------


def _wing(x: float, z: float, span: float, chord: float, sweep: float, thick: float) -> Part:
    """A pair of wings from the plane x = ``x``: one sheet (``thick`` 0) or a flat box."""
    if thick <= 0:
        v = np.array([[x + chord / 2, 0, z], [x - chord / 2, 0, z],
                      [x - sweep - chord / 4, span / 2, z], [x - sweep + chord / 4, span / 2, z],
                      [x - sweep - chord / 4, -span / 2, z], [x - sweep + chord / 4, -span / 2, z]])  # fmt: skip
        return v, np.array([[0, 1, 2], [0, 2, 3], [1, 0, 5], [1, 5, 4]])
    return box((x - sweep / 2, 0, z), (chord, span, thick))


def airplane(rng: Rng) -> list[Part]:
    length, r = vary(rng, 2.6, 0.3), vary(rng, 0.15, 0.3)
    parts = [ellipsoid((0, 0, 0), (length / 2, r, r))]
    span, chord = vary(rng, 2.4, 0.3), vary(rng, 0.4, 0.3)
    thick = 0.0 if rng.random() < 0.5 else 0.03
    parts.append(_wing(0.05 * length, -0.3 * r, span, chord, rng.uniform(0, 0.5), thick))
    tail = -length / 2 + 0.12
    parts.append(
        sheet(((tail + 0.2, 0, r * 0.5), (tail - 0.1, 0, r * 0.5), (tail - 0.12, 0, r + 0.35)))
    )
    parts.append(_wing(tail, 0.2 * r, span * rng.uniform(0.25, 0.4), 0.2, 0.1, thick))
    if rng.random() < 0.7:  # engines
        n = 1 if rng.random() < 0.6 else 2
        for sy in (-1, 1):
            for k in range(n):
                y = sy * span * (0.2 + 0.15 * k)
                parts.append(rod((0.2, y, -0.3 * r - 0.08), (-0.15, y, -0.3 * r - 0.08), 0.06, n=8))
    return parts


def biplane(rng: Rng) -> list[Part]:
    length, r = vary(rng, 1.6, 0.25), vary(rng, 0.14, 0.25)
    parts = [box((0, 0, 0), (length, 2 * r, 2 * r)) if rng.random() < 0.5
             else ellipsoid((0, 0, 0), (length / 2, r, r))]  # fmt: skip
    span, chord, gap = vary(rng, 2.0, 0.25), vary(rng, 0.35, 0.25), vary(rng, 0.4, 0.3)
    thick = 0.0 if rng.random() < 0.5 else 0.03
    x = 0.2 * length
    parts += [
        _wing(x, -r, span, chord, 0, thick),
        _wing(x + 0.05, -r + gap, span * 0.95, chord, 0, thick),
    ]
    for sy in (-1, 1):  # struts
        for dx in (-0.1, 0.1):
            parts.append(rod((x + dx, sy * span * 0.35, -r), (x + dx + 0.05, sy * span * 0.35, -r + gap),
                             0.01, n=4))  # fmt: skip
    tail = -length / 2 + 0.1
    parts.append(
        sheet(((tail + 0.15, 0, r * 0.5), (tail - 0.1, 0, r * 0.5), (tail - 0.1, 0, r + 0.3)))
    )
    parts.append(_wing(tail, 0, 0.6, 0.18, 0, 0))
    prop = quad((length / 2 + 0.02, 0, 0), (0, 0.35, 0), (0, 0, 0.03))
    parts.append(prop)
    for sy in (-1, 1):  # landing gear
        parts.append(rod((x, sy * 0.2, -r), (x, sy * 0.3, -r - 0.3), 0.01, n=4))
        parts.append(wheel((x, sy * 0.3, -r - 0.3), 0.08, 0.04))
    return parts


def helicopter(rng: Rng) -> list[Part]:
    lc, r = vary(rng, 1.0, 0.3), vary(rng, 0.3, 0.3)
    parts = [ellipsoid((0, 0, 0), (lc / 2, r, r * rng.uniform(0.9, 1.3)))]
    boom = vary(rng, 1.1, 0.3)
    parts.append(rod((-lc / 2 + 0.1, 0, 0.1), (-lc / 2 - boom, 0, 0.2), 0.05, n=6))
    parts.append(sheet(((-lc / 2 - boom + 0.1, 0, 0.2), (-lc / 2 - boom - 0.1, 0, 0.2),
                        (-lc / 2 - boom - 0.15, 0, 0.45))))  # fmt: skip
    parts.append(rod((0, 0, r), (0, 0, r + 0.15), 0.03, n=6))
    n, blade = int(rng.integers(2, 6)), vary(rng, 1.2, 0.3)
    for k in range(n):
        a = np.pi * k / n * (2 if n > 2 else 1)
        d = np.array([np.cos(a), np.sin(a), 0])
        e = np.array([-np.sin(a), np.cos(a), 0]) * 0.05
        c = np.array([0, 0, r + 0.15]) + d * blade / 2
        parts.append(quad(c, d * blade / 2, e))
    parts.append(quad((-lc / 2 - boom, 0.05, 0.3), (0.2, 0, 0), (0, 0, 0.02)))  # tail rotor
    if rng.random() < 0.7:  # skids
        for sy in (-1, 1):
            parts.append(
                rod((-0.5 * lc, sy * r, -r - 0.15), (0.5 * lc, sy * r, -r - 0.15), 0.02, n=6)
            )
            for x in (-0.25 * lc, 0.25 * lc):
                parts.append(rod((x, sy * r, -r - 0.15), (x, sy * 0.5 * r, -0.8 * r), 0.015, n=4))
    return parts


def glider(rng: Rng) -> list[Part]:
    length, r = vary(rng, 1.6, 0.25), vary(rng, 0.08, 0.3)
    parts = [revolve(np.linspace(-length / 2, length / 2, 5),
                     r * np.array([0.3, 0.6, 1.0, 0.9, 0.4]), n=8, top=True)]  # fmt: skip
    parts[0] = (place(parts[0][0], np.zeros(3), np.array([1.0, 0, 0])), parts[0][1])
    span, chord = vary(rng, 3.6, 0.3), vary(rng, 0.18, 0.3)
    thick = 0.0 if rng.random() < 0.6 else 0.02
    parts.append(_wing(0.1 * length, r * 0.7, span, chord, rng.uniform(0, 0.1), thick))
    tail = -length / 2 + 0.05
    fin = rng.uniform(0.2, 0.35)
    parts.append(sheet(((tail + 0.15, 0, 0), (tail - 0.05, 0, 0), (tail - 0.08, 0, fin))))
    z_stab = fin if rng.random() < 0.6 else 0.0  # T-tail
    parts.append(_wing(tail, z_stab, vary(rng, 0.6, 0.3), 0.1, 0, 0))
    if rng.random() < 0.4:  # canopy
        parts.append(ellipsoid((0.25 * length, 0, r * 0.8), (0.2, r * 0.7, r * 0.6)))
    return parts


# --------------------------------------------------------------------------------------
# Boats
# --------------------------------------------------------------------------------------


def _hull(length: float, w: float, h: float, bow: float) -> Part:
    """An open-decked hull: a pointed bow at +x."""
    v = np.array([
        [-length / 2, -w / 2, h], [length / 2, -w / 2, h], [length / 2 + bow, 0, h],
        [length / 2, w / 2, h], [-length / 2, w / 2, h], [-length / 2, -w / 3, 0],
        [length / 2, -w / 3, 0], [length / 2, w / 3, 0], [-length / 2, w / 3, 0],
    ])  # fmt: skip
    f = np.array([[5, 6, 1], [5, 1, 0], [6, 2, 1], [6, 7, 2], [7, 3, 2], [7, 8, 4], [7, 4, 3],
                  [8, 5, 0], [8, 0, 4], [5, 8, 7], [5, 7, 6]])  # fmt: skip
    return v, f


def ship(rng: Rng) -> list[Part]:
    length, w, h = vary(rng, 2.6, 0.3), vary(rng, 0.5, 0.25), vary(rng, 0.3, 0.3)
    parts: list[Part] = [_hull(length, w, h, vary(rng, 0.3, 0.4))]
    if rng.random() < 0.6:
        parts.append(hquad((0, 0, h), length, w))
    x = -0.1 * length
    for k in range(int(rng.integers(1, 4))):
        parts.append(box((x - 0.15 * k, 0, h + 0.12 + 0.1 * k), (0.5 - 0.1 * k, w * 0.6, 0.24)))
    for k in range(int(rng.integers(0, 3))):  # funnels
        parts.append(cylinder((x + 0.2 + 0.25 * k, 0, h + 0.2), 0.06, vary(rng, 0.35, 0.3), n=10))
    if rng.random() < 0.6:
        parts.append(rod((0.25 * length, 0, h), (0.25 * length, 0, h + vary(rng, 0.7, 0.3)), 0.02))
    return parts


def sailboat(rng: Rng) -> list[Part]:
    length, w, h = vary(rng, 1.6, 0.3), vary(rng, 0.45, 0.25), vary(rng, 0.2, 0.3)
    parts: list[Part] = [_hull(length, w, h, vary(rng, 0.3, 0.4))]
    mh, mx = vary(rng, 2.0, 0.3), rng.uniform(-0.05, 0.2) * length
    parts.append(rod((mx, 0, h), (mx, 0, h + mh), 0.02, n=6))
    boom = vary(rng, 0.8, 0.3) * length / 1.6
    parts.append(
        sheet(((mx, 0, h + 0.15), (mx, 0, h + mh * 0.95), (mx - boom, 0, h + 0.15)))
    )  # main
    if rng.random() < 0.7:  # jib
        parts.append(sheet(((mx + 0.03, 0, h + mh * 0.8), (mx + 0.03, 0, h + 0.15),
                            (length / 2 + 0.2, 0, h + 0.1))))  # fmt: skip
    if rng.random() < 0.6:  # keel
        parts.append(quad((0, 0, -0.2), (0.2, 0, 0), (0, 0, 0.2)))
    if rng.random() < 0.3:  # cabin
        parts.append(box((-0.1 * length, 0, h + 0.08), (0.4 * length, 0.6 * w, 0.16)))
    return parts


def submarine(rng: Rng) -> list[Part]:
    length, r = vary(rng, 3.0, 0.3), vary(rng, 0.22, 0.3)
    z = np.linspace(-length / 2, length / 2, 7)
    prof = r * np.array([0.15, 0.8, 1.0, 1.0, 1.0, 0.85, 0.3])
    v, f = revolve(z, prof, n=14, top=True)
    parts: list[Part] = [(place(v, np.zeros(3), np.array([1.0, 0, 0])), f)]
    sl, sh = vary(rng, 0.45, 0.3), vary(rng, 0.35, 0.4)
    sx = rng.uniform(0.0, 0.25) * length
    parts.append(box((sx, 0, r + sh / 2 - 0.05), (sl, 0.12, sh)) if rng.random() < 0.5 else
                 prism(np.array([[sx - sl / 2, r - 0.05], [sx + sl / 2, r - 0.05],
                                 [sx + sl / 3, r + sh], [sx - sl / 2, r + sh]]), -0.06, 0.06))  # fmt: skip
    if rng.random() < 0.5:  # sail planes
        parts.append(hquad((sx, 0, r + sh * 0.6), 0.15, 0.6))
    tx = -length / 2 + 0.25
    parts.append(quad((tx, 0, 0), (0.15, 0, 0), (0, 0, 2.2 * r)))  # cross tail
    parts.append(hquad((tx, 0, 0), 0.3, 4.4 * r))
    if rng.random() < 0.6:
        parts.append(quad((-length / 2 - 0.03, 0, 0), (0, 0.25, 0), (0, 0, 0.04)))  # propeller
    return parts


#: Builders of this module by kind name.
BUILDERS = {
    "house": house, "two_story_home": two_story_home, "skyscraper": skyscraper,
    "church": church, "tower": tower, "car": car, "truck": truck, "bus": bus,
    "train_car": train_car, "airplane": airplane, "biplane": biplane,
    "helicopter": helicopter, "glider": glider, "ship": ship, "sailboat": sailboat,
    "submarine": submarine,
}  # fmt: skip
