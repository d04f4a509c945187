"""Builders of the ``web`` set's furniture and household kinds (see :mod:`bench.sets.web_shapes`).

Each builder takes a seeded generator and returns the parts of one model, z up,
standing on z = 0, in metres. Close families on purpose: seven kinds of seat, five
of table, three of storage furniture, two lamps, three vessels. Within a kind the
proportions vary by up to about 40 %, parts are optional and styles differ (box or
sheet tops, box, round or splayed legs, slatted or solid backs).
"""

from __future__ import annotations

import numpy as np

from bench.sets.mesh_parts import Part, Rng, box, ellipsoid, hquad, quad, revolve, rod

__all__ = [
    "vary", "slab", "panel", "legs", "cylinder", "BUILDERS",
]  # fmt: skip


def vary(rng: Rng, x: float, p: float = 0.4) -> float:
    """``x`` scaled by a factor uniform in ``[1 - p, 1 + p]``."""
    return float(x * rng.uniform(1 - p, 1 + p))


def slab(rng: Rng, c: tuple[float, float, float], sx: float, sy: float, t: float) -> Part:
    """A horizontal top whose upper face is at ``c[2]``: a box or, a third of the time, a sheet."""
    if rng.random() < 1 / 3:
        return hquad(c, sx, sy)
    return box((c[0], c[1], c[2] - t / 2), (sx, sy, t))


def panel(rng: Rng, c: tuple[float, float, float], size: tuple[float, float, float]) -> Part:
    """An axis-aligned board of full sizes ``size``: a box, or a sheet across its thinnest axis."""
    if rng.random() < 0.5:
        return box(c, size)
    k = int(np.argmin(size))
    a, b = [i for i in range(3) if i != k]
    ea, eb = np.zeros(3), np.zeros(3)
    ea[a], eb[b] = size[a] / 2, size[b] / 2
    return quad(c, ea, eb)


def cylinder(c: tuple[float, float, float], r: float, h: float, *, n: int = 16,
             top: bool = True) -> Part:  # fmt: skip
    """A vertical cylinder of radius ``r`` from ``c[2]`` to ``c[2] + h`` (bottom capped)."""
    return revolve(np.array([c[2], c[2] + h]), np.array([r, r]), n=n, top=top, c=(c[0], c[1]))


def legs(rng: Rng, w: float, d: float, h: float, t: float, *, style: int | None = None,
         inset: float = 0.0) -> list[Part]:  # fmt: skip
    """Four legs of height ``h`` under a ``w`` x ``d`` top: box, round or splayed (``style`` 0-2)."""
    style = int(rng.integers(3)) if style is None else style
    x, y = w / 2 - t / 2 - inset, d / 2 - t / 2 - inset
    out: list[Part] = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            if style == 0:
                out.append(box((sx * x, sy * y, h / 2), (t, t, h)))
            elif style == 1:
                out.append(rod((sx * x, sy * y, 0), (sx * x, sy * y, h), t / 2, n=8))
            else:
                out.append(rod((sx * (x + 0.2 * h), sy * (y + 0.2 * h), 0), (sx * x, sy * y, h),
                               t / 2, n=6))  # fmt: skip
    return out


# --------------------------------------------------------------------------------------
# Seats
# --------------------------------------------------------------------------------------


def _back(rng: Rng, w: float, y: float, z0: float, bh: float) -> list[Part]:
    """A chair back from height ``z0``: solid, slatted, ladder or a frame with a panel."""
    style = int(rng.integers(4))
    if style == 0:
        return [panel(rng, (0, y, z0 + bh / 2), (w, 0.03, bh))]
    posts = [box((sx * (w / 2 - 0.02), y, z0 + bh / 2), (0.035, 0.035, bh)) for sx in (-1, 1)]
    if style == 1:  # vertical slats
        n = int(rng.integers(2, 6))
        xs = np.linspace(-w / 2 + 0.08, w / 2 - 0.08, n)
        return (
            posts
            + [box((x, y, z0 + bh / 2), (0.03, 0.015, bh)) for x in xs]
            + [box((0, y, z0 + bh), (w, 0.03, 0.06))]
        )
    if style == 2:  # ladder
        n = int(rng.integers(2, 5))
        return posts + [box((0, y, z0 + bh * (k + 1) / (n + 1)), (w, 0.02, 0.05))
                        for k in range(n)]  # fmt: skip
    return posts + [quad((0, y, z0 + 0.6 * bh), (w / 2 - 0.03, 0, 0), (0, 0.03, 0.35 * bh))]


def dining_chair(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 0.45, 0.2), vary(rng, 0.45, 0.2), vary(rng, 0.46, 0.1)
    parts = legs(rng, w, d, h, vary(rng, 0.04, 0.3)) + [slab(rng, (0, 0, h + 0.04), w, d, 0.04)]
    parts += _back(rng, w, -d / 2 + 0.02, h + 0.04, vary(rng, 0.45, 0.3))
    if rng.random() < 0.4:  # stretchers
        for sy in (-1, 1):
            parts.append(box((0, sy * (d / 2 - 0.03), 0.15), (w - 0.04, 0.02, 0.03)))
    return parts


def armchair(rng: Rng) -> list[Part]:
    w, d = vary(rng, 0.8, 0.25), vary(rng, 0.8, 0.2)
    hs, arm, leg = vary(rng, 0.42, 0.15), vary(rng, 0.15, 0.4), vary(rng, 0.1, 0.5)
    parts = [box((0, 0.03, (leg + hs) / 2), (w - 2 * arm, d - 0.1, hs - leg))]  # seat
    bh = vary(rng, 0.5, 0.35)
    parts.append(box((0, -d / 2 + 0.08, hs + bh / 2 - 0.1), (w, 0.16, bh + hs - leg)))
    ha = hs + vary(rng, 0.2, 0.4)
    for sx in (-1, 1):
        parts.append(box((sx * (w - arm) / 2, 0, (leg + ha) / 2), (arm, d, ha - leg)))
    if rng.random() < 0.6:  # cushion
        parts.append(ellipsoid((0, 0.05, hs + 0.04), ((w - 2 * arm) / 2, d / 2.5, 0.06)))
    if leg > 0.07:
        parts += legs(rng, w - 0.05, d - 0.05, leg + 0.01, 0.05, style=int(rng.integers(2)))
    return parts


def office_chair(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 0.5, 0.2), vary(rng, 0.48, 0.2), vary(rng, 0.48, 0.15)
    parts = [slab(rng, (0, 0, h + 0.06), w, d, 0.08)]
    bh = vary(rng, 0.55, 0.4)
    parts.append(box((0, -d / 2 + 0.03, h + 0.12 + bh / 2), (w * 0.95, 0.05, bh)))
    parts.append(rod((0, 0, 0.1), (0, 0, h), vary(rng, 0.03, 0.3), n=8))  # gas column
    n, reach = int(rng.integers(4, 6)), vary(rng, 0.32, 0.2)
    for k in range(n):
        a = 2 * np.pi * k / n
        foot = np.array([reach * np.cos(a), reach * np.sin(a), 0.06])
        parts.append(rod((0, 0, 0.1), foot, 0.02, n=6))
        parts.append(ellipsoid(foot - [0, 0, 0.03], (0.03, 0.03, 0.03)))
    if rng.random() < 0.6:  # arms
        for sx in (-1, 1):
            parts.append(box((sx * w / 2, 0, h + 0.18), (0.04, 0.04, 0.2)))
            parts.append(box((sx * w / 2, 0.02, h + 0.28), (0.06, d * 0.6, 0.03)))
    return parts


def stool(rng: Rng) -> list[Part]:
    r, h = vary(rng, 0.18, 0.3), vary(rng, 0.48, 0.15)
    n = int(rng.integers(3, 5))
    square = rng.random() < 0.4
    parts = [slab(rng, (0, 0, h), 2 * r, 2 * r, 0.04) if square
             else cylinder((0, 0, h - 0.04), r, 0.04)]  # fmt: skip
    for k in range(n):
        a = 2 * np.pi * (k + 0.5) / n
        top = (0.75 * r * np.cos(a), 0.75 * r * np.sin(a), h)
        foot = (1.15 * r * np.cos(a), 1.15 * r * np.sin(a), 0.0)
        parts.append(rod(foot, top, vary(rng, 0.02, 0.3), n=6))
    if rng.random() < 0.5:
        parts.append(revolve(np.array([0.35 * h, 0.35 * h + 0.02]), np.array([0.9 * r, 0.9 * r]),
                             bottom=False))  # fmt: skip
    return parts


def bar_stool(rng: Rng) -> list[Part]:
    r, h = vary(rng, 0.18, 0.25), vary(rng, 0.78, 0.12)
    parts = [cylinder((0, 0, h - 0.05), r, 0.05)]
    if rng.random() < 0.5:  # pedestal
        parts.append(rod((0, 0, 0.02), (0, 0, h - 0.05), vary(rng, 0.035, 0.3), n=8))
        parts.append(cylinder((0, 0, 0), vary(rng, 0.22, 0.25), 0.03))
    else:
        for k in range(4):
            a = np.pi / 4 + np.pi / 2 * k
            parts.append(rod((1.3 * r * np.cos(a), 1.3 * r * np.sin(a), 0),
                             (0.7 * r * np.cos(a), 0.7 * r * np.sin(a), h - 0.05), 0.02, n=6))  # fmt: skip
    zr = vary(rng, 0.3, 0.2)
    parts.append(revolve(np.array([zr, zr + 0.025]), np.array([r * 1.1, r * 1.1]), bottom=False))
    if rng.random() < 0.4:  # low back
        parts.append(box((0, -r, h + 0.15), (1.6 * r, 0.03, 0.2)))
    return parts


def bench(rng: Rng) -> list[Part]:
    length, d, h = vary(rng, 1.5, 0.35), vary(rng, 0.4, 0.3), vary(rng, 0.45, 0.1)
    parts: list[Part] = []
    if rng.random() < 0.5:  # slats
        n = int(rng.integers(3, 6))
        for y in np.linspace(-d / 2 + 0.04, d / 2 - 0.04, n):
            parts.append(box((0, y, h - 0.02), (length, d / n * 0.8, 0.03)))
    else:
        parts.append(slab(rng, (0, 0, h), length, d, 0.05))
    if rng.random() < 0.5:  # slab ends
        for sx in (-1, 1):
            parts.append(panel(rng, (sx * (length / 2 - 0.1), 0, h / 2), (0.05, d, h)))
    else:
        k = 2 if length < 1.6 else 3
        for x in np.linspace(-length / 2 + 0.1, length / 2 - 0.1, k):
            for sy in (-1, 1):
                parts.append(box((x, sy * (d / 2 - 0.04), h / 2), (0.05, 0.05, h)))
    if rng.random() < 0.5:  # park-bench back
        bh = vary(rng, 0.4, 0.3)
        parts.append(box((0, -d / 2, h + 0.05 + bh / 2), (length, 0.03, bh)))
        for sx in (-1, 1):
            parts.append(box((sx * (length / 2 - 0.1), -d / 2, h + bh / 2), (0.05, 0.05, bh + 0.1)))
    return parts


def sofa(rng: Rng) -> list[Part]:
    length, d = vary(rng, 2.0, 0.35), vary(rng, 0.9, 0.2)
    hs, arm = vary(rng, 0.42, 0.15), vary(rng, 0.18, 0.4)
    parts = [box((0, 0, hs / 2), (length, d, hs - 0.05))]
    bh = vary(rng, 0.45, 0.3)
    parts.append(box((0, -d / 2 + 0.1, hs + bh / 2), (length, 0.2, bh)))
    ha = vary(rng, 0.6, 0.2)
    if rng.random() < 0.85:
        for sx in (-1, 1):
            parts.append(box((sx * (length - arm) / 2, 0, ha / 2), (arm, d, ha)))
    n = int(rng.integers(2, 5))
    cw = (length - 2 * arm) / n
    for k in range(n):
        x = -length / 2 + arm + cw * (k + 0.5)
        parts.append(box((x, 0.05, hs + 0.05), (cw * 0.97, d - 0.25, 0.1)))
        if rng.random() < 0.5:
            parts.append(ellipsoid((x, -d / 2 + 0.25, hs + bh / 2), (cw / 2.2, 0.08, bh / 2.5)))
    if rng.random() < 0.3:  # chaise
        parts.append(box((length / 2 - 0.4, d / 2 + 0.35, hs / 2), (0.8, 0.7, hs)))
    return parts


# --------------------------------------------------------------------------------------
# Tables
# --------------------------------------------------------------------------------------


def table(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 1.6, 0.35), vary(rng, 0.85, 0.3), vary(rng, 0.75, 0.08)
    parts = legs(rng, w, d, h, vary(rng, 0.06, 0.3), inset=rng.uniform(0, 0.12))
    parts.append(slab(rng, (0, 0, h), w, d, 0.04))
    if rng.random() < 0.5:  # apron
        for sy in (-1, 1):
            parts.append(box((0, sy * (d / 2 - 0.1), h - 0.08), (w - 0.25, 0.025, 0.1)))
    if rng.random() < 0.3:  # stretcher
        parts.append(box((0, 0, 0.2), (w - 0.3, 0.04, 0.04)))
    return parts


def round_table(rng: Rng) -> list[Part]:
    r, h = vary(rng, 0.5, 0.35), vary(rng, 0.74, 0.08)
    t = 0.04
    parts = [revolve(np.array([h]), np.array([r]), n=24) if rng.random() < 1 / 3
             else cylinder((0, 0, h - t), r, t, n=24)]  # fmt: skip
    style = int(rng.integers(3))
    if style == 0:  # pedestal
        parts.append(rod((0, 0, 0.03), (0, 0, h - t), vary(rng, 0.06, 0.3), n=10))
        parts.append(cylinder((0, 0, 0), vary(rng, 0.25, 0.3), 0.03, n=16))
    elif style == 1:  # pedestal on feet
        parts.append(rod((0, 0, 0.05), (0, 0, h - t), vary(rng, 0.06, 0.3), n=10))
        for k in range(int(rng.integers(3, 5))):
            a = 2 * np.pi * k / 4
            parts.append(box((0.15 * np.cos(a), 0.15 * np.sin(a), 0.03), (0.3, 0.05, 0.05)))
    else:
        parts += legs(rng, 1.2 * r, 1.2 * r, h - t, 0.05)
    return parts


def coffee_table(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 1.1, 0.35), vary(rng, 0.6, 0.3), vary(rng, 0.42, 0.2)
    parts = [slab(rng, (0, 0, h), w, d, 0.05)]
    if rng.random() < 0.3:  # solid sides
        for sx in (-1, 1):
            parts.append(panel(rng, (sx * (w / 2 - 0.03), 0, h / 2), (0.05, d, h)))
    else:
        parts += legs(rng, w, d, h - 0.03, vary(rng, 0.05, 0.3), inset=rng.uniform(0, 0.08))
    if rng.random() < 0.5:  # lower shelf
        parts.append(slab(rng, (0, 0, 0.12), w * 0.9, d * 0.9, 0.02))
    return parts


def desk(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 1.4, 0.3), vary(rng, 0.7, 0.25), vary(rng, 0.75, 0.06)
    parts = [slab(rng, (0, 0, h), w, d, 0.03)]
    dw = vary(rng, 0.4, 0.25)
    n_ped = 1 if rng.random() < 0.6 else 2
    for k in range(n_ped):
        s = 1 if k == 0 else -1
        parts.append(box((s * (w / 2 - dw / 2), 0, (h - 0.03) / 2), (dw, d * 0.95, h - 0.03)))
        for j in range(int(rng.integers(0, 4))):  # drawer fronts and handles
            z = (h - 0.03) * (j + 0.5) / 3
            parts.append(rod((s * (w / 2 - dw / 2) - 0.05, d * 0.48, z),
                             (s * (w / 2 - dw / 2) + 0.05, d * 0.48, z), 0.01, n=6))  # fmt: skip
    if n_ped == 1:
        parts.append(panel(rng, (-(w / 2 - 0.02), 0, h / 2), (0.03, d, h)))
    if rng.random() < 0.6:
        parts.append(quad((0, -d / 2 + 0.03, h * 0.6), (w / 2 - 0.05, 0, 0), (0, 0, h * 0.3)))
    if rng.random() < 0.25:  # hutch
        parts.append(box((0, -d / 2 + 0.12, h + 0.3), (w, 0.25, 0.6)))
    return parts


def school_desk(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 0.65, 0.2), vary(rng, 0.48, 0.2), vary(rng, 0.72, 0.12)
    tilt = rng.uniform(0, 0.2)
    top_c = np.array([0, 0, h])
    a, b = np.array([w / 2, 0, 0]), np.array([0, d / 2 * np.cos(tilt), d / 2 * np.sin(tilt)])
    parts = [quad(top_c, a, b) if rng.random() < 0.5 else box(top_c, (w, d, 0.03))]
    for sx in (-1, 1):  # tubular frame
        x = sx * (w / 2 - 0.04)
        parts.append(rod((x, -d / 2 + 0.05, 0), (x, -d / 2 + 0.05, h), 0.015, n=6))
        parts.append(rod((x, d / 2 - 0.05, 0), (x, d / 2 - 0.05, h), 0.015, n=6))
        parts.append(rod((x, -d / 2, 0.01), (x, d / 2, 0.01), 0.015, n=6))
    if rng.random() < 0.7:  # book box
        parts.append(box((0, 0, h - 0.12), (w - 0.1, d - 0.1, 0.1)))
    if rng.random() < 0.5:  # attached seat
        zs, ys = 0.42, -d / 2 - 0.35
        parts.append(box((0, ys, zs), (0.4, 0.38, 0.03)))
        parts.append(box((0, ys - 0.18, zs + 0.2), (0.38, 0.02, 0.25)))
        parts.append(rod((0, ys, 0), (0, ys, zs), 0.02, n=6))
        parts.append(rod((0, ys + 0.1, 0.01), (0, -d / 2 + 0.05, 0.01), 0.015, n=6))
    return parts


# --------------------------------------------------------------------------------------
# Storage, bed, stairs
# --------------------------------------------------------------------------------------


def _carcass(rng: Rng, w: float, d: float, h: float, z0: float) -> list[Part]:
    """Sides, top and bottom of a cabinet body (boards or sheets)."""
    parts = [panel(rng, (sx * w / 2, 0, z0 + h / 2), (0.02, d, h)) for sx in (-1, 1)]
    parts += [slab(rng, (0, 0, z), w, d, 0.02) for z in (z0 + 0.02, z0 + h)]
    return parts


def bookshelf(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 0.9, 0.35), vary(rng, 0.32, 0.25), vary(rng, 1.6, 0.3)
    parts = _carcass(rng, w, d, h, 0.0)
    n = int(rng.integers(2, 7))
    parts += [hquad((0, 0, h * k / (n + 1)), w, d) for k in range(1, n + 1)]
    if rng.random() < 0.6:
        parts.append(quad((0, -d / 2, h / 2), (w / 2, 0, 0), (0, 0, h / 2)))
    if rng.random() < 0.3:  # books
        for _ in range(int(rng.integers(3, 10))):
            z = h * int(rng.integers(0, n + 1)) / (n + 1) + 0.12
            parts.append(box((rng.uniform(-w / 2 + 0.1, w / 2 - 0.1), 0, z), (0.04, d * 0.8, 0.22)))
    return parts


def cabinet(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 0.9, 0.35), vary(rng, 0.45, 0.25), vary(rng, 0.9, 0.3)
    leg = 0.1 if rng.random() < 0.5 else 0.0
    parts = _carcass(rng, w, d, h, leg)
    parts.append(quad((0, -d / 2, leg + h / 2), (w / 2, 0, 0), (0, 0, h / 2)))
    n = int(rng.integers(1, 4))
    for k in range(n):  # doors or drawers with handles
        x = -w / 2 + w * (k + 0.5) / n
        parts.append(quad((x, d / 2 + 0.005, leg + h / 2), (w / (2 * n) - 0.01, 0, 0),
                          (0, 0, h / 2 - 0.02)))  # fmt: skip
        parts.append(rod((x + 0.3 * w / n, d / 2 + 0.01, leg + h * 0.45),
                         (x + 0.3 * w / n, d / 2 + 0.01, leg + h * 0.6), 0.01, n=6))  # fmt: skip
    if leg:
        parts += legs(rng, w, d, leg, 0.04)
    return parts


def wardrobe(rng: Rng) -> list[Part]:
    w, d, h = vary(rng, 1.1, 0.35), vary(rng, 0.58, 0.2), vary(rng, 2.0, 0.12)
    parts = _carcass(rng, w, d, h, 0.08)
    parts.append(box((0, 0, 0.04), (w - 0.04, d - 0.04, 0.08)))  # plinth
    n = int(rng.integers(2, 4))
    for k in range(n):
        x = -w / 2 + w * (k + 0.5) / n
        parts.append(panel(rng, (x, d / 2 + 0.01, 0.08 + h / 2), (w / n - 0.01, 0.02, h - 0.02)))
        parts.append(rod((x + 0.35 * w / n, d / 2 + 0.03, h * 0.45),
                         (x + 0.35 * w / n, d / 2 + 0.03, h * 0.65), 0.012, n=6))  # fmt: skip
    if rng.random() < 0.5:  # crown
        parts.append(box((0, 0, h + 0.12), (w + 0.08, d + 0.06, 0.06)))
    return parts


def bed(rng: Rng) -> list[Part]:
    w, length = vary(rng, 1.4, 0.35), vary(rng, 2.0, 0.08)
    hm = vary(rng, 0.45, 0.2)
    parts = legs(rng, w, length, 0.15, 0.06) + [box((0, 0, 0.15 + (hm - 0.15) / 2),
                                                   (w, length, hm - 0.15))]  # fmt: skip
    hb = vary(rng, 1.0, 0.25)
    parts.append(panel(rng, (0, -length / 2, hb / 2), (w + 0.05, 0.05, hb)))
    if rng.random() < 0.5:  # footboard
        parts.append(panel(rng, (0, length / 2, hm / 2 + 0.1), (w + 0.05, 0.04, hm + 0.2)))
    for k in range(int(rng.integers(0, 3))):  # pillows
        x = 0 if w < 1.1 else (k - 0.5) * w / 2.2
        parts.append(ellipsoid((x, -length / 2 + 0.25, hm + 0.05), (0.25, 0.15, 0.06)))
    if rng.random() < 0.4:  # blanket
        parts.append(quad((0, 0.2, hm + 0.02), (w / 2 + 0.05, 0, 0), (0, length / 3, 0)))
    return parts


def staircase(rng: Rng) -> list[Part]:
    n, w = int(rng.integers(4, 15)), vary(rng, 1.1, 0.35)
    rise, run = vary(rng, 0.18, 0.15), vary(rng, 0.28, 0.15)
    parts: list[Part] = []
    sheets = rng.random() < 0.5
    for k in range(n):
        if not sheets:
            parts.append(box((0, k * run, (k + 0.5) * rise), (w, run, rise)))
        else:
            parts.append(hquad((0, k * run, (k + 1) * rise), w, run))
            parts.append(quad((0, (k - 0.5) * run, (k + 0.5) * rise), (w / 2, 0, 0),
                              (0, 0, rise / 2)))  # fmt: skip
    for sx in (-1, 1) if rng.random() < 0.5 else (1,):
        x = sx * w / 2
        parts.append(rod((x, 0, rise + 0.9), (x, (n - 1) * run, n * rise + 0.9), 0.025))
        for k in range(0, n, 3):
            parts.append(rod((x, k * run, (k + 1) * rise), (x, k * run, (k + 1) * rise + 0.9),
                             0.02))  # fmt: skip
    return parts


# --------------------------------------------------------------------------------------
# Lamps and vessels
# --------------------------------------------------------------------------------------


def _shade(rng: Rng, c: tuple[float, float, float], r: float, h: float) -> Part:
    """An open conical lamp shade centred at ``c``."""
    return revolve(np.array([c[2] - h / 2, c[2] + h / 2]), np.array([r, r * rng.uniform(0.5, 1.0)]),
                   bottom=False, c=(c[0], c[1]))  # fmt: skip


def floor_lamp(rng: Rng) -> list[Part]:
    h, rb = vary(rng, 1.6, 0.2), vary(rng, 0.15, 0.3)
    parts = [cylinder((0, 0, 0), rb, 0.03)]
    if rng.random() < 0.3:  # arc lamp
        mid = np.array([0.3 * h, 0, 0.9 * h])
        tip = np.array([0.6 * h, 0, 0.75 * h])
        parts += [rod((0, 0, 0.03), mid, 0.015), rod(mid, tip, 0.015)]
        parts.append(_shade(rng, (tip[0], 0, tip[2] - 0.1), vary(rng, 0.2, 0.3), 0.2))
    else:
        parts.append(rod((0, 0, 0.03), (0, 0, h), vary(rng, 0.015, 0.3)))
        parts.append(_shade(rng, (0, 0, h), vary(rng, 0.22, 0.3), vary(rng, 0.3, 0.3)))
    return parts


def desk_lamp(rng: Rng) -> list[Part]:
    rb = vary(rng, 0.09, 0.3)
    parts = [cylinder((0, 0, 0), rb, 0.025) if rng.random() < 0.6
             else box((0, 0, 0.0125), (2 * rb, 1.5 * rb, 0.025))]  # fmt: skip
    a1, a2 = rng.uniform(0.1, 0.6), rng.uniform(0.6, 1.6)
    l1, l2 = vary(rng, 0.35, 0.3), vary(rng, 0.32, 0.3)
    p1 = np.array([l1 * np.sin(a1), 0, 0.025 + l1 * np.cos(a1)])
    p2 = p1 + [l2 * np.sin(a2), 0, l2 * np.cos(a2)]
    parts += [rod((0, 0, 0.025), p1, 0.01, n=6), rod(p1, p2, 0.01, n=6)]
    parts.append(ellipsoid(p1, (0.02, 0.02, 0.02)))
    v, f = revolve(np.array([0.0, 0.12]), np.array([0.03, vary(rng, 0.08, 0.3)]), bottom=False)
    parts.append((v @ np.array([[1, 0, 0], [0, 1, 0], [0, 0, -1.0]]) + p2, f))  # head, opening down
    return parts


def bottle(rng: Rng) -> list[Part]:
    h, r = vary(rng, 0.3, 0.35), vary(rng, 0.04, 0.35)
    neck = rng.uniform(0.25, 0.5)
    shoulder = rng.uniform(0.5, 0.75)
    z = np.array([0, 0.02, shoulder, shoulder + 0.12, 0.9, 1.0]) * h
    rr = r * np.array([0.9, 1.0, 1.0, 0.5 + 0.4 * rng.random(), neck, neck])
    parts = [revolve(z, rr, n=16, top=rng.random() < 0.3)]
    if rng.random() < 0.5:  # cap
        parts.append(cylinder((0, 0, h), r * neck * 1.2, 0.08 * h, n=12))
    return parts


def vase(rng: Rng) -> list[Part]:
    h, r = vary(rng, 0.4, 0.35), vary(rng, 0.15, 0.35)
    k = int(rng.integers(5, 9))
    z = np.linspace(0, h, k)
    belly = rng.uniform(0.3, 0.7)
    rr = r * (0.55 + 0.45 * np.exp(-(((z / h) - belly) ** 2) / 0.06)) * rng.uniform(0.9, 1.1, k)
    rr[-1] = r * rng.uniform(0.5, 1.1)  # lip
    parts = [revolve(z, rr, n=20)]
    if rng.random() < 0.3:  # handles
        for s in (-1, 1):
            parts.append(rod((s * rr[-2], 0, 0.85 * h), (s * (r + 0.05), 0, 0.6 * h), 0.012, n=6))
    if rng.random() < 0.25:  # flowers
        for _ in range(int(rng.integers(2, 6))):
            tip = (rng.normal(0, 0.1), rng.normal(0, 0.1), h * rng.uniform(1.3, 1.8))
            parts.append(rod((0, 0, 0.5 * h), tip, 0.005, n=4))
            parts.append(ellipsoid(tip, (0.04, 0.04, 0.03)))
    return parts


def mug(rng: Rng) -> list[Part]:
    h, r = vary(rng, 0.1, 0.3), vary(rng, 0.045, 0.3)
    parts = [revolve(np.array([0, h]), np.array([r, r * rng.uniform(0.95, 1.25)]), n=20)]
    if rng.random() < 0.5:  # wall thickness: an inner sheet
        parts.append(revolve(np.array([0.01, h]), np.array([0.85 * r, 0.9 * r]), n=20))
    if rng.random() < 0.85:  # handle: three rods
        a, b = np.array([r, 0, 0.8 * h]), np.array([r, 0, 0.2 * h])
        out = vary(rng, 0.04, 0.3)
        parts += [rod(a, a + [out, 0, 0], 0.007, n=6), rod(a + [out, 0, 0], b + [out, 0, 0],
                  0.007, n=6), rod(b + [out, 0, 0], b, 0.007, n=6)]  # fmt: skip
    if rng.random() < 0.3:  # saucer
        parts.append(revolve(np.array([-0.005, 0.005]), np.array([2.2 * r, 2.5 * r]), n=20))
    return parts


#: Builders of this module by kind name.
BUILDERS = {
    "dining_chair": dining_chair, "armchair": armchair, "office_chair": office_chair,
    "stool": stool, "bar_stool": bar_stool, "bench": bench, "sofa": sofa,
    "table": table, "round_table": round_table, "coffee_table": coffee_table, "desk": desk,
    "school_desk": school_desk, "bookshelf": bookshelf, "cabinet": cabinet,
    "wardrobe": wardrobe, "bed": bed, "staircase": staircase, "floor_lamp": floor_lamp,
    "desk_lamp": desk_lamp, "bottle": bottle, "vase": vase, "mug": mug,
}  # fmt: skip
