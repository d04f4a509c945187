"""Builders of the ``enclosures`` set's kinds (see :mod:`bench.sets.enclosures`).

Thin-walled, enclosing man-made kinds built as web and CAD models are: walls are
single zero-thickness sheets (or thin boards) with doors, windows and vents left as
gaps, boxes are open, parts overlap without being joined. Each builder takes a
seeded generator and returns the parts of one model, z up, standing on z = 0, in the
builder's own units (metres for a house, a bracket's tens of millimetres as 0.0x).
Close pairs on purpose: house and rail car (pierced wall shells), desk and bookcase
(boards and open boxes), sink and housing (an open box in a plate), wheel and dish
(round), book and bracket (bent flat sheets), tent and boat (single-sided shells).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from bench.sets.mesh_parts import Part, Rng, box, hquad, quad, revolve, rod, rotation, sheet
from bench.sets.mesh_parts import transform as moved
from bench.sets.web_furniture import panel, slab, vary
from bench.sets.web_structures import roof
from bench.sets.web_structures import wheel as closed_wheel
from bench.sets.webplus_made import arc_points, tube

__all__ = ["join", "pierced", "plate", "tray", "loft", "row", "BUILDERS"]

X, Y, Z = np.eye(3)
#: A gap in a pierced sheet: (u0, u1, v0, v1) along its length and height.
Gap = tuple[float, float, float, float]


def join(parts: Sequence[Part]) -> Part:
    """One part of several: vertices concatenated, faces re-indexed, nothing merged."""
    starts = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
    v = np.concatenate([np.asarray(p[0], dtype=float) for p in parts])
    f = np.concatenate(
        [np.asarray(p[1], dtype=np.int64) + s for p, s in zip(parts, starts, strict=True)]
    )
    return v, f


def pierced(corner: ArrayLike, u: ArrayLike, v: ArrayLike, length: float, height: float,
            gaps: Sequence[Gap] = ()) -> Part:  # fmt: skip
    """A zero-thickness rectangle ``corner + a u + b v`` (a in [0, length], b in [0, height])
    with rectangular ``gaps`` (u0, u1, v0, v1) cut out, as the strips that remain."""
    c, u, v = (np.asarray(x, dtype=float) for x in (corner, u, v))
    cuts = sorted({0.0, length, *(min(max(x, 0.0), length) for g in gaps for x in g[:2])})
    strips: list[Part] = []
    for a0, a1 in zip(cuts[:-1], cuts[1:], strict=True):
        spans = [(0.0, height)]
        for g0, g1, lo, hi in gaps:
            if g0 <= (a0 + a1) / 2 <= g1:
                spans = [s for b0, b1 in spans for s in ((b0, min(b1, lo)), (max(b0, hi), b1))]
        for b0, b1 in spans:
            if b1 - b0 > 1e-9 and a1 - a0 > 1e-9:
                strips.append(sheet([c + a0 * u + b0 * v, c + a1 * u + b0 * v,
                                     c + a1 * u + b1 * v, c + a0 * u + b1 * v]))  # fmt: skip
    return join(strips)


def row(length: float, n: int, fill: float, lo: float, hi: float) -> list[Gap]:
    """``n`` gaps spread evenly along ``length``, each ``fill`` of its slot wide, from ``lo`` to ``hi``."""
    slot = length / n
    return [((k + 0.5 - fill / 2) * slot, (k + 0.5 + fill / 2) * slot, lo, hi) for k in range(n)]


def plate(centre: ArrayLike, u: ArrayLike, v: ArrayLike, length: float, width: float,
          holes: Sequence[float] = (), r: float = 0.4) -> Part:  # fmt: skip
    """A zero-thickness rectangle ``length`` along unit ``u`` by ``width`` along unit ``v``
    with round holes of radius ``r`` x width/2 centred at ``holes`` (positions along ``u``
    from the centre); holes that overlap or stick out are left out."""
    c, u, v = (np.asarray(x, dtype=float) for x in (centre, u, v))
    hw, kept = width / 2, []
    for x in sorted(holes):
        if abs(x) + hw <= length / 2 and (not kept or x - kept[-1] >= width):
            kept.append(x)
    ends = [-length / 2, *(e for x in kept for e in (x - hw, x + hw)), length / 2]
    pieces = [quad(c + (a + b) / 2 * u, (b - a) / 2 * u, hw * v)
              for a, b in zip(ends[0::2], ends[1::2], strict=True) if b - a > 1e-9]  # fmt: skip
    t = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    ring = np.column_stack([np.cos(t), np.sin(t)])
    loc = np.vstack([ring / np.abs(ring).max(axis=1, keepdims=True), r * ring]) * hw
    j = np.arange(16)
    faces = np.concatenate([np.column_stack([j, (j + 1) % 16, 16 + (j + 1) % 16]),
                            np.column_stack([j, 16 + (j + 1) % 16, 16 + j])])  # fmt: skip
    for x in kept:
        pieces.append((c + (loc[:, :1] + x) * u + loc[:, 1:] * v, faces))
    return join(pieces)


def tray(c: ArrayLike, size: ArrayLike, *, t: float = 0.0, open_side: int = 5) -> list[Part]:
    """An open box: five walls of a box centred at ``c`` of full sizes ``size``, the
    ``open_side`` one (0-5: -x, +x, -y, +y, -z, +z) missing; zero-thickness sheets, or
    boards ``t`` thick (overlapping at the corners) when ``t`` > 0."""
    c, s = np.asarray(c, dtype=float), np.asarray(size, dtype=float)
    out: list[Part] = []
    for k in range(6):
        if k == open_side:
            continue
        axis, side = divmod(k, 2)
        at = c.copy()
        at[axis] += (side - 0.5) * s[axis]
        if t > 0:
            out.append(box(at, np.where(np.arange(3) == axis, t, s)))
            continue
        a, b = (i for i in range(3) if i != axis)
        out.append(quad(at, np.eye(3)[a] * s[a] / 2, np.eye(3)[b] * s[b] / 2))
    return out


def loft(sections: Sequence[ArrayLike]) -> Part:
    """An open sheet through polylines ``sections`` (each (k, 3), the same k), in order."""
    v = np.concatenate([np.asarray(s, dtype=float) for s in sections])
    k = len(v) // len(sections)
    faces = [[i * k + j, i * k + j + 1, (i + 1) * k + j + 1] for i in range(len(sections) - 1)
             for j in range(k - 1)]  # fmt: skip
    faces += [[i * k + j, (i + 1) * k + j + 1, (i + 1) * k + j] for i in range(len(sections) - 1)
              for j in range(k - 1)]  # fmt: skip
    return v, np.asarray(faces, dtype=np.int64)


def _xz(profile: ArrayLike, y: float) -> np.ndarray:
    """(k, 3) points of a profile (k, 2) in the x-z plane at ``y``."""
    p = np.asarray(profile, dtype=float)
    return np.column_stack([p[:, 0], np.full(len(p), y), p[:, 1]])


def _thin(rng: Rng, scale: float) -> float:
    """A wall thickness: zero (a sheet) half of the time, else about 1 % of ``scale``."""
    return 0.0 if rng.random() < 0.5 else vary(rng, 0.01 * scale, 0.3)


# --------------------------------------------------------------------------------------
# Pierced shells: house, rail car
# --------------------------------------------------------------------------------------


def _facade(rng: Rng, length: float, h: float, door: bool) -> list[Gap]:
    """Windows along a wall (some left out), one of them a door when ``door``."""
    gaps = row(length, max(1, int(length / vary(rng, 3.0, 0.3))), rng.uniform(0.3, 0.6),
               0.35 * h, 0.75 * h)  # fmt: skip
    gaps = [g for g in gaps if rng.random() < 0.8]
    if door:
        x = rng.uniform(0.15, 0.85) * length
        gaps = [g for g in gaps if g[1] < x - 0.6 or g[0] > x + 0.6] + [
            (x - 0.5, x + 0.5, 0, 0.8 * h)
        ]
    return gaps


def house(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 10.0, 0.3), vary(rng, 8.0, 0.3), vary(rng, 2.8, 0.15)
    storeys = 1 + int(rng.random() < 0.35)
    corners = np.array([[-w / 2, -d / 2], [w / 2, -d / 2], [w / 2, d / 2], [-w / 2, d / 2]])
    parts: list[Part] = []
    for k in range(storeys):
        for i in range(4):
            a, b = corners[i], corners[(i + 1) % 4]
            length = float(np.linalg.norm(b - a))
            gaps = _facade(rng, length, h, door=i == 0 and k == 0)
            parts.append(pierced((*a, k * h), np.append((b - a) / length, 0), Z, length, h, gaps))
        parts.append(hquad((0, 0, k * h), w, d))
        for _ in range(int(rng.integers(1, 4))):  # partitions, each with a doorway
            along = int(rng.integers(2))
            span, at = (d, w) if along else (w, d)
            x = rng.uniform(-0.3, 0.3) * at
            a = np.array([x, -span / 2] if along else [-span / 2, x])
            door = rng.uniform(0.1, 0.7) * span
            parts.append(pierced((*a, k * h), Y if along else X, Z, span, h,
                                 [(door, door + 0.9, 0, 0.75 * h)]))  # fmt: skip
    parts += roof(rng, w, d, storeys * h, vary(rng, 2.5, 0.4))
    if rng.random() < 0.5:  # chimney
        parts.append(box((w / 4, d / 5, storeys * h + 1.5), (0.6, 0.6, 3.0)))
    return parts


def rail_car(rng: Rng) -> list[Part]:
    length, w, h = vary(rng, 14.0, 0.25), vary(rng, 2.8, 0.1), vary(rng, 2.6, 0.15)
    z0, r = vary(rng, 1.1, 0.1), vary(rng, 0.45, 0.15)
    freight = rng.random() < 0.35
    parts = [hquad((0, 0, z0), length, w)]
    for sy in (-1, 1):
        if freight:  # a sliding door's opening
            gaps = [(0.4 * length, 0.6 * length, 0.0, 0.85 * h)]
        else:
            gaps = row(length, int(rng.integers(6, 13)), rng.uniform(0.5, 0.8), 0.4 * h, 0.8 * h)
        parts.append(pierced((-length / 2, sy * w / 2, z0), X, Z, length, h, gaps))
    for sx in (-1, 1):  # ends, with a gangway door or closed
        gaps = [(0.35 * w, 0.65 * w, 0, 0.85 * h)] if rng.random() < 0.6 else []
        parts.append(pierced((sx * length / 2, -w / 2, z0), Y, Z, w, h, gaps))
    arc = arc_points(-w / 2, w / 2, vary(rng, 0.4, 0.4), z0 + h)
    parts.append(loft([arc + [-length / 2, 0, 0], arc + [length / 2, 0, 0]]))
    for bx in (-0.35 * length, 0.35 * length):  # bogies
        parts.append(box((bx, 0, r + 0.1), (4 * r, 0.8 * w, 0.25)))
        parts += [closed_wheel((bx + sx * 1.2 * r, sy * 0.7 * w / 2, r), r, 0.15)
                  for sx in (-1, 1) for sy in (-1, 1)]  # fmt: skip
    parts += [box((sx * (length / 2 + 0.3), 0, z0), (0.6, 0.3, 0.3)) for sx in (-1, 1)]
    if not freight and rng.random() < 0.4:  # seats inside
        parts += [box((x, sy * w / 4, z0 + 0.25), (0.5, 0.4 * w, 0.5))
                  for x in np.linspace(-0.4, 0.4, 6) * length for sy in (-1, 1)]  # fmt: skip
    return parts


# --------------------------------------------------------------------------------------
# Boards and open boxes: desk, bookcase
# --------------------------------------------------------------------------------------


def _pedestal(rng: Rng, x: float, pw: float, d: float, h: float, t: float) -> list[Part]:
    """A column of open-box drawers under a desk top, some pulled out, in a carcass."""
    parts = tray((x, 0, h / 2), (pw, d, h), t=t, open_side=2)
    n = int(rng.integers(2, 5))
    dh = h / n
    for k in range(n):
        out = rng.uniform(0, 0.6) * d if rng.random() < 0.4 else 0.0
        c = (x, -out, (k + 0.5) * dh)
        parts += tray(c, (0.9 * pw, 0.95 * d, 0.8 * dh), t=t)
        parts.append(quad((x, -d / 2 - out, c[2]), (pw / 2, 0, 0), (0, 0, 0.48 * dh)))
        parts.append(box((x, -d / 2 - out - 0.015, c[2] + 0.25 * dh), (0.3 * pw, 0.02, 0.02)))
    return parts


def desk(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 1.4, 0.3), vary(rng, 0.7, 0.2), vary(rng, 0.75, 0.08)
    t = _thin(rng, 2.0)
    parts = [slab(rng, (0, 0, h), w, d, 0.03)]
    style = int(rng.integers(3))
    pw = vary(rng, 0.4, 0.2) * min(w, 1.4) / 1.4
    if style > 0:
        parts += _pedestal(rng, w / 2 - pw / 2, pw, d, h - 0.03, t)
    if style == 2:
        parts += _pedestal(rng, -w / 2 + pw / 2, pw, d, h - 0.03, t)
    else:
        parts.append(panel(rng, (-w / 2 + 0.02, 0, h / 2), (0.03, d, h)))
        if style == 0:
            parts.append(panel(rng, (w / 2 - 0.02, 0, h / 2), (0.03, d, h)))
    if rng.random() < 0.6:  # modesty panel
        parts.append(quad((0, d / 2 - 0.05, 0.6 * h), (w / 2 - 0.05, 0, 0), (0, 0, 0.3 * h)))
    if rng.random() < 0.3:  # hutch of shelves on top
        parts += tray((0, d / 2 - 0.15, h + 0.3), (w, 0.3, 0.6), t=t, open_side=2)
    return parts


def bookcase(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 0.9, 0.4), vary(rng, 0.32, 0.25), vary(rng, 1.8, 0.45)
    t = max(_thin(rng, 2.0), 0.018) if rng.random() < 0.7 else 0.0
    parts = tray((0, 0, h / 2), (w, d, h), t=t, open_side=2)  # sides, back, bottom, top
    if rng.random() < 0.3:  # no back
        del parts[2]
    n = max(1, int(h / vary(rng, 0.35, 0.25)))
    parts += [panel(rng, (0, 0, z), (w, d, 0.02)) for z in np.linspace(0, h, n + 1)[1:-1]]
    if w > 1.0 and rng.random() < 0.6:  # a divider
        parts.append(panel(rng, (rng.uniform(-0.2, 0.2) * w, 0, h / 2), (0.02, d, h)))
    if rng.random() < 0.35:  # doors on the lower part, ajar
        for sx in (-1, 1):
            a = rng.uniform(0, 1.2)
            door = quad((sx * w / 4, -d / 2, 0.2 * h), (w / 4, 0, 0), (0, 0, 0.2 * h))
            parts.append(moved(moved(door, shift=(-sx * w / 2, d / 2, 0)), rotation(2, sx * a),
                               (sx * w / 2, -d / 2, 0)))  # fmt: skip
    if rng.random() < 0.3:  # plinth
        parts.append(quad((0, -d / 2, 0.04), (w / 2, 0, 0), (0, 0, 0.04)))
    return parts


# --------------------------------------------------------------------------------------
# Open boxes in plates: sink, housing
# --------------------------------------------------------------------------------------


def _tap(rng: Rng, x: float, y: float, z: float, reach: float) -> list[Part]:
    th = vary(rng, 0.2, 0.4)
    parts = [
        rod((x, y, z), (x, y, z + th), 0.015),
        rod((x, y, z + th), (x, y - reach, z + th), 0.012),
    ]
    if rng.random() < 0.6:  # handles
        parts += [rod((x + s * 0.07, y, z), (x + s * 0.07, y, z + 0.06), 0.02) for s in (-1, 1)]
    return parts


def sink(rng: Rng) -> list[Part]:
    w, d, top = vary(rng, 1.0, 0.35), vary(rng, 0.55, 0.15), vary(rng, 0.9, 0.1)
    depth = vary(rng, 0.18, 0.3)
    n = 2 if w > 2.1 * d and rng.random() < 0.5 else 1
    xs = [0.0] if n == 1 else [-w / 4, w / 4]
    if rng.random() < 0.5:  # round bowls in a holed counter
        rho = rng.uniform(0.6, 0.85)
        parts = [plate((0, 0, top), X, Y, w, d, xs, rho)]
        rs = rho * d / 2 * np.array([0.45, 0.8, 0.95, 1.0])
        parts += [revolve(top - depth * np.array([1, 0.7, 0.3, 0]), rs, n=20, c=(x, 0)) for x in xs]
    else:  # square basins in a cut-out counter
        bw, bd = min(0.8 * w / n, vary(rng, 0.5, 0.2)), 0.75 * d
        gaps = [
            (x + w / 2 - bw / 2, x + w / 2 + bw / 2, d / 2 - bd / 2, d / 2 + bd / 2) for x in xs
        ]
        parts = [pierced((-w / 2, -d / 2, top), X, Y, w, d, gaps)]
        for x in xs:
            parts += tray((x, 0, top - depth / 2), (bw, bd, depth), t=_thin(rng, 0.3))
    for x in xs:
        parts += _tap(rng, x, d / 2 - 0.06, top, rng.uniform(0.1, 0.25) * d)
    under = int(rng.integers(3))
    if under == 0:  # vanity cabinet, open at the front
        parts += tray((0, 0, (top - 0.05) / 2), (w, d, top - 0.05), open_side=2)
    elif under == 1:  # pedestal
        parts.append(revolve(np.array([0, top - depth]), np.array([0.15, 0.08]) * d / 0.55, n=12))
    if rng.random() < 0.6:  # splashback
        parts.append(quad((0, d / 2, top + 0.1), (w / 2, 0, 0), (0, 0, 0.1)))
    return parts


def housing(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 0.3, 0.4), vary(rng, 0.2, 0.3), vary(rng, 0.08, 0.4)
    vents = row(d, int(rng.integers(5, 14)), 0.4, 0.3 * h, 0.75 * h)
    parts = [hquad((0, 0, 0), w, d)]
    for sx in (-1, 1):
        gaps = vents if rng.random() < 0.7 else []
        parts.append(pierced((sx * w / 2, -d / 2, 0), Y, Z, d, h, gaps))
    ports = row(w, int(rng.integers(1, 5)), 0.3, 0.3 * h, 0.7 * h) if rng.random() < 0.7 else []
    parts.append(pierced((-w / 2, -d / 2, 0), X, Z, w, h, ports))
    parts.append(pierced((-w / 2, d / 2, 0), X, Z, w, h))
    if rng.random() < 0.5:  # thin walls: an inner copy of every sheet
        t = vary(rng, 0.01, 0.3) * w
        parts += [
            (np.asarray(v) * [1 - 2 * t / w, 1 - 2 * t / d, 1] + [0, 0, t], f) for v, f in parts
        ]
    lid = tray((0, 0, -0.1 * h), (w, d, 0.2 * h), open_side=4) if rng.random() < 0.5 else None
    lid_parts = lid or [hquad((0, 0, 0), w, d)]
    a = rng.uniform(0.2, 1.6) if rng.random() < 0.7 else 0.0
    lift = 0.0 if a else vary(rng, 0.6, 0.5) * h  # lid ajar on its hinge, or lifted off
    parts += [moved(moved(p, rotation(0, -a)), shift=(0, d / 2, h + lift))
              for p in (moved(q, shift=(0, -d / 2, 0)) for q in lid_parts)]  # fmt: skip
    br = vary(rng, 0.04, 0.3) * min(w, d)
    for sx in (-1, 1):  # screw bosses: open tubes in the corners
        for sy in (-1, 1):
            c = (sx * (w / 2 - 1.5 * br), sy * (d / 2 - 1.5 * br))
            parts.append(
                revolve(np.array([0, 0.7 * h]), np.array([br, br]), n=10, bottom=False, c=c)
            )
    if rng.random() < 0.6:  # a board on standoffs
        parts.append(box((0, 0, 0.3 * h), (0.8 * w - 4 * br, 0.8 * d, 0.02 * h)))
    return parts


# --------------------------------------------------------------------------------------
# Round: wheel, dish
# --------------------------------------------------------------------------------------


def wheel(rng: Rng) -> list[Part]:
    r, width = vary(rng, 0.35, 0.3), vary(rng, 0.08, 0.6)
    n = int(rng.integers(3, 13))
    hub, rim = vary(rng, 0.12, 0.3) * r, vary(rng, 0.8, 0.1) * r
    zs = np.array([-width / 2, width / 2])
    if rng.random() < 0.5:  # tyre as a torus about the rim
        a = (r - rim) / 2
        phi = np.linspace(0, 2 * np.pi, 13)
        parts = [revolve(a * np.sin(phi), rim + a + a * np.cos(phi), n=32, bottom=False)]
    else:  # tyre and rim as two open cylinders and side walls
        parts = [revolve(zs, np.array([r, r]), n=32, bottom=False),
                 revolve(zs, np.array([rim, rim]), n=32, bottom=False)]  # fmt: skip
        if rng.random() < 0.6:
            parts += [revolve(np.array([z, z]), np.array([rim, r]), n=32, bottom=False) for z in zs]
    parts.append(revolve(1.5 * zs, np.array([hub, hub]), n=12, top=True))
    bar = rng.random() < 0.5
    for k in range(n):
        t = 2 * np.pi * k / n
        e = np.array([np.cos(t), np.sin(t), 0.0])
        if bar:  # flat spokes
            parts.append(
                quad(e * (hub + rim) / 2, e * (rim - hub) / 2 * 1.05, np.array([0, 0, 0.4 * width]))
            )
        else:
            parts.append(rod(e * hub * 0.8, e * rim * 1.02, vary(rng, 0.015, 0.3) * r, n=6))
    return [moved(p, rotation(0, np.pi / 2), (0, 0, r)) for p in parts]


def dish(rng: Rng) -> list[Part]:
    r = vary(rng, 0.6, 0.4)
    f = r * rng.uniform(0.35, 0.8)
    rs = np.linspace(0.05 * r, r, 6)
    parts = [revolve(rs**2 / (4 * f), rs, n=24)]  # single-sided, capped at the centre
    focus = np.array([0, 0, f])
    if rng.random() < 0.5:  # one arm from the rim's bottom
        parts.append(rod((r, 0, r * r / (4 * f)), focus, 0.015 * r))
    else:  # three or four struts
        k = int(rng.integers(3, 5))
        parts += [rod((r * np.cos(t), r * np.sin(t), r * r / (4 * f)), focus, 0.01 * r)
                  for t in np.linspace(0, 2 * np.pi, k, endpoint=False)]  # fmt: skip
    parts.append(revolve(f + np.array([-0.1, 0.0]) * r, np.array([0.04, 0.08]) * r, n=10))
    if rng.random() < 0.4:  # rim ring
        parts.append(revolve(np.array([0, 0.04]) * r + r * r / (4 * f), np.array([r, r]), n=24,
                             bottom=False))  # fmt: skip
    parts.append(revolve(np.array([-0.15 * r, 0.02 * r]), np.array([0.15, 0.15]) * r, n=12))
    height = vary(rng, 1.0, 0.4) * r
    tilt = rotation(1, np.pi / 2 - rng.uniform(0.25, 1.3))
    parts = [moved(p, tilt, (0, 0, height)) for p in parts]
    if rng.random() < 0.6:  # pole on a base plate
        parts += [rod((0, 0, 0), (0, 0, height), 0.04 * r), hquad((0, 0, 0), 0.5 * r, 0.5 * r)]
    else:  # tripod
        parts += [rod((0.6 * r * np.cos(t), 0.6 * r * np.sin(t), 0), (0, 0, height), 0.03 * r)
                  for t in (0.5, 2.6, 4.7)]  # fmt: skip
    return parts


# --------------------------------------------------------------------------------------
# Bent sheets: book, bracket
# --------------------------------------------------------------------------------------


def _book_half(w: float, h: float, th: float, ct: float) -> list[Part]:
    """A cover and its block of pages lying on z = 0 from the spine (x = 0) to x = ``w``."""
    cover = (
        box((w / 2, 0, ct / 2), (w, h, ct))
        if ct
        else quad((w / 2, 0, 0), (w / 2, 0, 0), (0, h / 2, 0))
    )
    return [cover, box((w / 2, 0, ct + th / 2), (0.96 * w, 0.96 * h, th))]


def book(rng: Rng) -> list[Part]:
    w, h, th = vary(rng, 0.15, 0.3), vary(rng, 0.22, 0.25), vary(rng, 0.03, 0.6)
    ct = 0.0 if rng.random() < 0.5 else vary(rng, 0.003, 0.3)
    if rng.random() < 0.45:  # closed: two covers, a spine and the pages between
        parts = _book_half(w, h, th, ct)
        parts.append(quad((w / 2, 0, th + ct), (w / 2, 0, 0), (0, h / 2, 0)))
        spine = arc_points(0, th + ct, rng.uniform(0, 0.3) * th, 0)[:, [2, 0, 1]] * [-1, 1, 1]
        parts.append(loft([spine + [0, -h / 2, 0], spine + [0, h / 2, 0]]))
        if rng.random() < 0.4:  # standing on its bottom edge
            parts = [moved(p, rotation(0, np.pi / 2), (0, 0, h / 2)) for p in parts]
        return parts
    a = rng.uniform(0.0, 0.5)  # each half lifted from the table by this angle
    half = _book_half(w, h, th / 2, ct)
    if rng.random() < 0.6:  # pages turning
        half += [moved(quad((w / 2, 0, 0), (w / 2, 0, 0), (0, h / 2, 0)), rotation(1, -b), (0, 0, th / 2))
                 for b in rng.uniform(0.3, 2.8, int(rng.integers(1, 4)))]  # fmt: skip
    right = [moved(p, rotation(1, -a)) for p in half]
    return right + [moved(p, rotation(2, np.pi)) for p in right[:2]]


def _profile(rng: Rng) -> np.ndarray:
    """(k, 2) x-z polyline of a bent bracket: L, U, Z or hat, flanges of varied lengths."""
    a, b, c = (vary(rng, 0.05, 0.45) for _ in range(3))
    kind = int(rng.integers(4))
    if kind == 0:
        return np.array([[a, 0], [0, 0], [0, b]])
    if kind == 1:
        return np.array([[0, b], [0, 0], [a, 0], [a, c]])
    if kind == 2:
        return np.array([[-a, 0], [0, 0], [0, b], [c, b]])
    return np.array([[-c, 0], [0, 0], [0, b], [a, b], [a, 0], [a + c, 0]])


def bracket(rng: Rng) -> list[Part]:
    prof, width = _profile(rng), vary(rng, 0.04, 0.4)
    t = vary(rng, 0.002, 0.3) if rng.random() < 0.5 else 0.0  # thin, or a single sheet
    parts: list[Part] = []
    for p, q in zip(prof[:-1], prof[1:], strict=True):
        length = float(np.linalg.norm(q - p))
        u = np.array([*(q - p) / length, 0.0])[[0, 2, 1]]
        centre = _xz([(p + q) / 2], 0.0)[0]
        n = int(rng.integers(0, 3)) if length > 1.5 * width else 0
        holes = np.linspace(-1, 1, n) * 0.999 * (length / 2 - width / 2) if n > 1 else [0.0] * n
        flange = plate(centre, u, Y, length, width, holes, rng.uniform(0.25, 0.5))
        parts.append(flange)
        if t:  # the sheet again across its thickness
            parts.append(moved(flange, shift=t * np.cross(u, Y)))
    if len(prof) == 3 and rng.random() < 0.5:  # gussets in the bend
        g = 0.5 * min(prof[0, 0], prof[2, 1])
        parts += [sheet([(0, y, 0), (g, y, 0), (0, y, g)]) for y in (-0.45 * width, 0.45 * width)]
    return parts


# --------------------------------------------------------------------------------------
# Single-sided shells: tent, boat
# --------------------------------------------------------------------------------------


def tent(rng: Rng) -> list[Part]:
    length, w, h = vary(rng, 2.4, 0.3), vary(rng, 1.8, 0.3), vary(rng, 1.3, 0.3)
    style = int(rng.integers(3))
    if style == 0:  # ridge tent: a roof folded over a ridge pole, a door in the front gable
        ridge = _xz([[-w / 2, 0], [0, h], [w / 2, 0]], 0)[:, [1, 0, 2]]
        parts = [loft([ridge - [length / 2, 0, 0], ridge + [length / 2, 0, 0]])]
        dw = rng.uniform(0.1, 0.35) * w
        parts += [sheet([(-length / 2, -w / 2, 0), (-length / 2, -dw, 0), (-length / 2, 0, h)]),
                  sheet([(-length / 2, dw, 0), (-length / 2, w / 2, 0), (-length / 2, 0, h)]),
                  sheet([(length / 2, -w / 2, 0), (length / 2, w / 2, 0), (length / 2, 0, h)])]  # fmt: skip
        parts += [rod((x, 0, 0), (x, 0, h * 1.05), 0.015) for x in (-length / 2, length / 2)]
        parts.append(rod((-length / 2, 0, h), (length / 2, 0, h), 0.012))
    elif style == 1:  # dome: crossed hoops under a faceted fabric dome
        phi = np.linspace(0, 0.45 * np.pi, 5)
        parts = [revolve(h * np.sin(phi), w / 2 * np.cos(phi), n=int(rng.integers(6, 12)), bottom=False,
                         top=True)]  # fmt: skip
        hoop = arc_points(-w / 2, w / 2, h, 0, 10)
        parts += [
            p for t in (np.pi / 4, -np.pi / 4) for p in tube(hoop @ rotation(2, t).T, 0.01, 5)
        ]
    else:  # bell or pyramid tent on a centre pole, an optional wall
        wall = rng.uniform(0, 0.5) * h if rng.random() < 0.5 else 0.0
        zs, rs = (
            np.array([0, wall, h])[int(wall == 0) :],
            np.array([w / 2, w / 2, 0.02])[int(wall == 0) :],
        )
        parts = [
            revolve(zs, rs, n=int(rng.integers(4, 13)), bottom=False),
            rod((0, 0, 0), (0, 0, 1.1 * h), 0.02),
        ]
    if rng.random() < 0.5:  # guy lines to pegs
        for t in np.linspace(0, 2 * np.pi, 4, endpoint=False) + np.pi / 4:
            e = np.array([np.cos(t), np.sin(t), 0])
            parts.append(rod(e * w * 0.45 + [0, 0, 0.6 * h], e * w * 0.9, 0.004, n=4))
    return parts


def _hull(rng: Rng, length: float, b: float, depth: float) -> tuple[Part, Part, np.ndarray]:
    """An open hull along x (bow at +x), its transom sheet and half-breadth per station."""
    xs = np.linspace(-length / 2, length / 2, 9)
    t = (xs + length / 2) / length
    half = (
        b / 2 * np.clip(1 - t ** vary(rng, 4.0, 0.3), 0.02, None) * (0.8 + 0.2 * np.sin(np.pi * t))
    )
    keel = depth * 0.5 * t**6  # the keel rises to the bow
    if rng.random() < 0.5:  # round bilge
        s = np.linspace(-np.pi / 2, np.pi / 2, 7)
        shape = np.column_stack([np.sin(s), 1 - np.cos(s)])
    else:  # hard chine
        shape = np.array([[-1, 1], [-0.8, 0.25], [0, 0], [0.8, 0.25], [1, 1]])
    rings = [np.column_stack([np.full(len(shape), x), hw * shape[:, 0], k + (depth - k) * shape[:, 1]])
             for x, hw, k in zip(xs, half, keel, strict=True)]  # fmt: skip
    return loft(rings), sheet(rings[0]), half


def boat(rng: Rng) -> list[Part]:
    length, b, depth = vary(rng, 5.0, 0.3), vary(rng, 1.8, 0.25), vary(rng, 0.8, 0.25)
    hull, transom, half = _hull(rng, length, b, depth)
    parts = [hull, transom]
    for k in range(int(rng.integers(1, 4))):  # thwarts
        i = 2 + 2 * k
        x = -length / 2 + length * i / 8
        parts.append(panel(rng, (x, 0, 0.7 * depth), (0.25, 2 * half[i] * 0.95, 0.03)))
    if rng.random() < 0.4:  # foredeck
        parts.append(loft([[[0.25 * length, -half[6], depth], [0.25 * length, half[6], depth]],
                           [[0.5 * length, -0.02, depth], [0.5 * length, 0.02, depth]]]))  # fmt: skip
    if rng.random() < 0.45:  # cabin: an open-backed box with windows
        cl, cw, ch = 0.3 * length, 0.75 * b, vary(rng, 0.8, 0.25)
        for sy in (-1, 1):
            parts.append(
                pierced(
                    (-cl / 2, sy * cw / 2, depth), X, Z, cl, ch, row(cl, 3, 0.6, 0.4 * ch, 0.8 * ch)
                )
            )
        parts.append(
            pierced(
                (cl / 2, -cw / 2, depth), Y, Z, cw, ch, [(0.2 * cw, 0.8 * cw, 0.4 * ch, 0.85 * ch)]
            )
        )
        parts.append(hquad((0, 0, depth + ch), cl * 1.1, cw * 1.05))
    elif rng.random() < 0.5:  # outboard motor
        parts += [box((-length / 2 - 0.15, 0, depth), (0.3, 0.25, 0.4)),
                  rod((-length / 2 - 0.15, 0, depth), (-length / 2 - 0.15, 0, -0.3), 0.04)]  # fmt: skip
    return parts


BUILDERS = {
    "house": house, "rail_car": rail_car, "desk": desk, "bookcase": bookcase, "sink": sink,
    "housing": housing, "wheel": wheel, "dish": dish, "book": book, "bracket": bracket,
    "tent": tent, "boat": boat,
}  # fmt: skip
