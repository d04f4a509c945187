"""Builders of the ``webplus`` set's structures (see :mod:`bench.sets.webplus_shapes`).

Four bridges (arch, suspension, truss, beam) and six towers (lighthouse, water tower,
silo, lattice pylon, guyed radio mast, wind turbine), z up, standing on z = 0, in
metres; proportions vary by up to about 40 %, part counts and styles vary with the seed.
"""

from __future__ import annotations

import numpy as np

from bench.sets.mesh_parts import Part, Rng, box, ellipsoid, quad, revolve, rod, sheet
from bench.sets.web_furniture import slab, vary
from bench.sets.webplus_made import arc_points, tube

__all__ = ["BUILDERS"]


# --------------------------------------------------------------------------------------
# Bridges
# --------------------------------------------------------------------------------------


def _deck(rng: Rng, length: float, w: float, z: float) -> list[Part]:
    """A deck along y at height ``z`` (box or sheet), with railings a third of the time."""
    parts = [slab(rng, (0, 0, z), w, length, 0.2)]
    if rng.random() < 1 / 3:
        for sx in (-1, 1):
            parts.append(quad((sx * w / 2, 0, z + 0.5), (0, length / 2, 0), (0, 0, 0.5)))
    return parts


def arch_bridge(rng: Rng) -> list[Part]:
    length, w = vary(rng, 30.0, 0.4), vary(rng, 5.0, 0.4)
    rise, z = length * vary(rng, 0.25, 0.4), vary(rng, 8.0, 0.4)
    over = rng.random() < 0.4  # a through arch above the deck, else a deck arch under it
    parts = _deck(rng, length, w, z)
    base = z if over else 0.0
    for sx in (-1, 1):
        pts = arc_points(-length / 2, length / 2, rise if over else z - 0.3, base)
        pts[:, 0] = sx * w / 2 * (0.9 if over else 0.6)
        parts += tube(pts, 0.04 * rise + 0.2, n=6)
        for p in pts[1:-1]:
            parts.append(rod(p, (p[0], p[1], z), 0.1, n=4))
    for sy in (-1, 1):  # abutments
        parts.append(box((0, sy * (length / 2 + 1.5), z / 2), (w * 1.2, 3.0, z)))
    return parts


def suspension_bridge(rng: Rng) -> list[Part]:
    span, w = vary(rng, 60.0, 0.4), vary(rng, 6.0, 0.4)
    side, z = span * rng.uniform(0.2, 0.5), vary(rng, 8.0, 0.4)
    tower = z + span * vary(rng, 0.15, 0.4)
    parts = _deck(rng, span + 2 * side, w, z)
    for sy in (-1, 1):
        for sx in (-1, 1):
            parts.append(box((sx * w / 2, sy * span / 2, tower / 2), (1.0, 1.5, tower)))
        for k in range(int(rng.integers(1, 4))):
            parts.append(box((0, sy * span / 2, tower - 1 - 0.3 * k * tower), (w, 1.0, 0.8)))
    sag = tower - z - 1.5
    for sx in (-1, 1):
        main = arc_points(-span / 2, span / 2, -sag, tower, k=12)
        main[:, 0] = sx * w / 2
        parts += tube(main, 0.3, n=5)
        for p in main[1:-1]:
            parts.append(rod(p, (p[0], p[1], z), 0.05, n=4))
        for sy in (-1, 1):  # back stays to the anchorages
            parts.append(rod((sx * w / 2, sy * span / 2, tower), (sx * w / 2, sy * (span / 2 + side), z),
                             0.3, n=5))  # fmt: skip
    return parts


def truss_bridge(rng: Rng) -> list[Part]:
    length, w = vary(rng, 40.0, 0.4), vary(rng, 5.0, 0.3)
    z, th = vary(rng, 6.0, 0.5), vary(rng, 5.0, 0.4)
    bays = int(rng.integers(4, 10))
    parts = _deck(rng, length, w, z)
    ys = np.linspace(-length / 2, length / 2, bays + 1)
    for sx in (-1, 1):
        x = sx * w / 2
        parts.append(box((x, 0, z), (0.3, length, 0.4)))
        parts.append(box((x, 0, z + th), (0.3, length * (1 - 1 / bays), 0.4)))
        for k, y in enumerate(ys):
            top = min(max(y, ys[1]), ys[-2])
            parts.append(rod((x, y, z), (x, top, z + th), 0.12, n=4))
            if 0 < k < bays and rng.random() < 0.8:
                nxt = ys[k + 1] if y < 0 else ys[k - 1]
                parts.append(rod((x, y, z + th), (x, nxt, z), 0.1, n=4))
    if rng.random() < 0.6:  # top bracing
        for y in ys[1:-1]:
            parts.append(box((0, y, z + th), (w, 0.2, 0.2)))
    parts += [box((0, sy * length / 2, z / 2), (w, 1.5, z)) for sy in (-1, 1)]  # piers
    return parts


# --------------------------------------------------------------------------------------
# Towers
# --------------------------------------------------------------------------------------


def lighthouse(rng: Rng) -> list[Part]:
    h, r = vary(rng, 20.0, 0.4), vary(rng, 2.5, 0.3)
    taper = rng.uniform(0.5, 0.95)
    parts = [revolve(np.array([0, h]), np.array([r, r * taper]), n=16)]
    rt = r * taper
    parts.append(revolve(np.array([h, h + 0.3]), np.array([rt + 0.8, rt + 0.8]), n=16, top=True))
    n = int(rng.integers(8, 17))
    for k in range(n):  # gallery railing
        a = 2 * np.pi * k / n
        parts.append(rod(((rt + 0.7) * np.cos(a), (rt + 0.7) * np.sin(a), h + 0.3),
                         ((rt + 0.7) * np.cos(a), (rt + 0.7) * np.sin(a), h + 1.3), 0.04, n=4))  # fmt: skip
    lh = vary(rng, 2.5, 0.3)
    parts.append(revolve(np.array([h + 0.3, h + 0.3 + lh]), np.array([0.7 * rt, 0.7 * rt]), n=12,
                         bottom=False))  # lantern room, glass  # fmt: skip
    parts.append(revolve(np.array([h + 0.3 + lh, h + 0.3 + lh + 0.8 * rt]), np.array([0.8 * rt, 0.05]),
                         n=12))  # fmt: skip
    if rng.random() < 0.5:  # keeper's house
        parts.append(box((r + 3, 0, 2), (6, 5, 4)))
    return parts


def water_tower(rng: Rng) -> list[Part]:
    h, r = vary(rng, 15.0, 0.4), vary(rng, 4.0, 0.4)
    style = int(rng.integers(3))
    if style == 0:  # spherical tank
        parts = [ellipsoid((0, 0, h + r), (r, r, r * rng.uniform(0.7, 1.0)))]
    else:  # cylinder with a cone roof
        th = r * vary(rng, 1.0, 0.4)
        parts = [revolve(np.array([h, h + th, h + th + 0.5 * r]), np.array([r, r, 0.1]), n=16)]
    if style == 2:  # a single column
        parts.append(revolve(np.array([0, h]), np.array([0.3 * r, 0.25 * r]), n=12))
        return parts
    legs = int(rng.choice([3, 4, 6, 8]))
    for k in range(legs):
        a = 2 * np.pi * k / legs
        foot = np.array([1.2 * r * np.cos(a), 1.2 * r * np.sin(a), 0])
        top = np.array([0.8 * r * np.cos(a), 0.8 * r * np.sin(a), h + 0.2 * r])
        parts.append(rod(foot, top, 0.15, n=6))
        b = 2 * np.pi * (k + 1) / legs
        nxt = np.array([1.0 * r * np.cos(b), 1.0 * r * np.sin(b), h / 2])
        if rng.random() < 0.7:
            parts.append(rod(foot + (top - foot) * 0.5, nxt, 0.05, n=4))
    return parts


def pylon(rng: Rng) -> list[Part]:
    h, base = vary(rng, 30.0, 0.35), vary(rng, 8.0, 0.35)
    top = base * rng.uniform(0.15, 0.35)
    levels = int(rng.integers(4, 9))
    parts: list[Part] = []
    corners = [(sx, sy) for sx in (-1, 1) for sy in (-1, 1)]
    for sx, sy in corners:
        parts.append(
            rod((sx * base / 2, sy * base / 2, 0), (sx * top / 2, sy * top / 2, h), 0.15, n=4)
        )
    zs = np.linspace(0, h, levels + 1)
    for i, z in enumerate(zs[1:], 1):
        s = base + (top - base) * z / h
        s0 = base + (top - base) * zs[i - 1] / h
        for k in range(4):  # a ring and a diagonal per face
            (ax, ay), (bx, by) = corners[[0, 1, 3, 2][k]], corners[[1, 3, 2, 0][k]]
            parts.append(rod((ax * s / 2, ay * s / 2, z), (bx * s / 2, by * s / 2, z), 0.06, n=4))
            parts.append(
                rod((ax * s0 / 2, ay * s0 / 2, zs[i - 1]), (bx * s / 2, by * s / 2, z), 0.05, n=4)
            )
    arms = int(rng.integers(1, 4))
    reach = vary(rng, 1.0, 0.4) * base
    for k in range(arms):
        z = h * (0.65 + 0.12 * k)
        parts.append(box((0, 0, z), (reach * (1 - 0.15 * k) * 2, 0.6, 0.8)))
        for sx in (-1, 1):  # insulators
            x = sx * reach * (1 - 0.15 * k) * 0.9
            parts.append(rod((x, 0, z), (x, 0, z - 2.0), 0.12, n=5))
    if rng.random() < 0.5:  # earth wire peak
        parts.append(rod((0, 0, h), (0, 0, h + 0.15 * h), 0.1, n=4))
    return parts


def wind_turbine(rng: Rng) -> list[Part]:
    h, blade = vary(rng, 80.0, 0.35), vary(rng, 40.0, 0.35)
    r = vary(rng, 2.0, 0.3)
    parts = [revolve(np.array([0, h]), np.array([r, 0.55 * r]), n=12, top=True)]
    parts.append(box((-0.5, 0, h + r), (4 * r, 1.6 * r, 1.6 * r)))
    hub = np.array([1.8 * r, 0, h + r])
    parts.append(ellipsoid(hub + [0.3 * r, 0, 0], (0.9 * r, 0.8 * r, 0.8 * r)))
    n, phase = (3 if rng.random() < 0.85 else 2), rng.uniform(0, 2 * np.pi)
    chord = blade * vary(rng, 0.07, 0.3)
    for k in range(n):
        a = phase + 2 * np.pi * k / n
        u = np.array([0, np.cos(a), np.sin(a)])
        side = np.array([0, -np.sin(a), np.cos(a)])
        root, tip = hub + 0.5 * r * u, hub + blade * u
        parts.append(sheet((root - 0.5 * chord * side, root + 0.5 * chord * side,
                            tip + 0.1 * chord * side, tip - 0.15 * chord * side)))  # fmt: skip
    return parts


def beam_bridge(rng: Rng) -> list[Part]:
    length, w = vary(rng, 40.0, 0.4), vary(rng, 6.0, 0.4)
    z, spans = vary(rng, 8.0, 0.5), int(rng.integers(2, 7))
    parts = _deck(rng, length, w, z)
    parts.append(box((0, 0, z - 0.6), (0.7 * w, length, 1.0)))  # girder
    for y in np.linspace(-length / 2, length / 2, spans + 1)[1:-1]:
        if rng.random() < 0.5:  # a wall pier or two columns with a cap
            parts.append(box((0, y, z / 2), (0.8 * w, 1.2, z)))
        else:
            for sx in (-1, 1):
                parts.append(rod((sx * w / 3, y, 0), (sx * w / 3, y, z - 1), 0.5, n=8))
            parts.append(box((0, y, z - 1.2), (w, 1.5, 0.8)))
    parts += [box((0, sy * (length / 2 + 1.5), z / 2), (w * 1.1, 3.0, z)) for sy in (-1, 1)]
    return parts


def silo(rng: Rng) -> list[Part]:
    h, r = vary(rng, 18.0, 0.4), vary(rng, 3.0, 0.4)
    n = 1 if rng.random() < 0.5 else int(rng.integers(2, 5))
    parts: list[Part] = []
    for k in range(n):
        x = (k - (n - 1) / 2) * 2.05 * r
        hk = h * vary(rng, 1.0, 0.1)
        parts.append(revolve(np.array([0, hk]), np.array([r, r]), n=14, c=(x, 0)))
        if rng.random() < 0.6:  # dome or cone
            parts.append(revolve(np.array([hk, hk + 0.5 * r]), np.array([r, 0.1]), n=14, c=(x, 0)))
        else:
            parts.append(ellipsoid((x, 0, hk), (r, r, 0.6 * r)))
    if rng.random() < 0.5:  # conveyor leg and head house
        parts.append(box((0, r + 1, h * 0.6), (1.5, 1.5, 1.2 * h)))
        parts.append(rod((0, r + 1, h * 1.1), (n * r + 4, r + 1, 2), 0.3, n=5))
    return parts


def radio_mast(rng: Rng) -> list[Part]:
    h, s = vary(rng, 60.0, 0.4), vary(rng, 1.5, 0.3)
    parts: list[Part] = []
    corners = [(np.cos(a), np.sin(a)) for a in 2 * np.pi * np.arange(3) / 3]
    for cx, cy in corners:
        parts.append(rod((s * cx, s * cy, 0), (s * cx, s * cy, h), 0.08, n=4))
    levels = int(rng.integers(8, 20))
    for z0, z1 in zip(np.linspace(0, h, levels)[:-1], np.linspace(0, h, levels)[1:], strict=True):
        for k in range(3):
            (ax, ay), (bx, by) = corners[k], corners[(k + 1) % 3]
            parts.append(rod((s * ax, s * ay, z0), (s * bx, s * by, z1), 0.04, n=4))
    guys = int(rng.integers(1, 4))
    reach = h * vary(rng, 0.5, 0.3)
    for g in range(guys):
        z = h * (0.35 + 0.6 * (g + 1) / (guys + 1))
        for cx, cy in corners:
            parts.append(rod((s * cx, s * cy, z), (reach * cx, reach * cy, 0), 0.03, n=4))
    for _ in range(int(rng.integers(0, 4))):  # dishes and antennae
        z, a = rng.uniform(0.5, 0.95) * h, rng.uniform(0, 2 * np.pi)
        c = np.array([(s + 1) * np.cos(a), (s + 1) * np.sin(a), z])
        parts.append(ellipsoid(c, (0.3, 1.0, 1.0)) if rng.random() < 0.5
                     else rod(c, c + [0, 0, 4.0], 0.1, n=4))  # fmt: skip
    return parts


#: Builders of this module by kind name.
BUILDERS = {
    "arch_bridge": arch_bridge, "suspension_bridge": suspension_bridge,
    "truss_bridge": truss_bridge, "beam_bridge": beam_bridge, "lighthouse": lighthouse,
    "water_tower": water_tower, "silo": silo, "pylon": pylon, "radio_mast": radio_mast,
    "wind_turbine": wind_turbine,
}  # fmt: skip
