"""Families of machined parts as implicit CSG (private; see :func:`shapedb.examples.part`).

Each builder takes a seeded :class:`numpy.random.Generator` and returns one member of
its family: proportions, feature counts and positions vary with the seed, the kind
stays recognisable. Every part is about unit scale (1 to 3 model units across) and is
built only from primitives and CSG, so its bounds always contain the solid.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from shapedb.geometry.implicit import Box, Capsule, Cylinder, Implicit, Union

__all__ = ["BUILDERS", "rotation"]

_X, _Y, _Z = np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0])


def rotation(axis: NDArray[np.float64], angle: float) -> NDArray[np.float64]:
    """Rotation matrix (3, 3) about the unit ``axis`` by ``angle`` radians (Rodrigues)."""
    a = axis / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def _through_holes(
    centres: list[tuple[float, float]], radius: float, z0: float, z1: float
) -> list[Implicit]:
    """Vertical (z) cylinders through the slab ``z0 <= z <= z1`` at ``centres`` (x, y)."""
    return [Cylinder([x, y, z0 - 1.0], [x, y, z1 + 1.0], radius) for x, y in centres]


def _ring(n: int, radius: float, phase: float) -> list[tuple[float, float]]:
    """``n`` points evenly spaced on a circle of ``radius`` about the z axis."""
    return [
        (radius * np.cos(phase + 2 * np.pi * k / n), radius * np.sin(phase + 2 * np.pi * k / n))
        for k in range(n)
    ]


# -- the original three ----------------------------------------------------------------
def _plate(rng: np.random.Generator) -> Implicit:
    L, W, T = rng.uniform(2.0, 3.0), rng.uniform(1.0, 1.6), rng.uniform(0.15, 0.3)
    body: Implicit = Box([0, 0, T / 2], [L, W, T])
    adds: list[Implicit] = []
    for _ in range(int(rng.integers(1, 3))):  # bosses on top
        x, y = rng.uniform(-0.3 * L, 0.3 * L), rng.uniform(-0.25 * W, 0.25 * W)
        adds.append(
            Cylinder([x, y, T - 0.01], [x, y, T + rng.uniform(0.15, 0.4)], rng.uniform(0.12, 0.22))
        )
    for k in range(int(rng.integers(0, 3))):  # ribs along x
        y = (k - 0.5) * 0.4 * W
        adds.append(Box([0, y, T + 0.1], [0.8 * L, 0.06, 0.2]))
    body = Union(body, *adds)
    r = rng.uniform(0.06, 0.12)
    corners = [(sx * (L / 2 - 0.2), sy * (W / 2 - 0.2)) for sx in (-1, 1) for sy in (-1, 1)]
    tools = _through_holes(corners[: int(rng.integers(2, 5))], r, 0.0, T)
    if rng.random() < 0.7:  # a through slot: a capsule swept through the plate
        y, half = rng.uniform(-0.2, 0.2) * W, rng.uniform(0.2, 0.4)
        tools.append(
            Union(
                Box([0, y, T / 2], [2 * half, 2 * r, T + 2.0]),
                *_through_holes([(-half, y), (half, y)], r, 0.0, T),
            )
        )
    return body - Union(*tools)


def _bracket(rng: np.random.Generator) -> Implicit:
    L, W, T = rng.uniform(1.2, 2.0), rng.uniform(0.8, 1.4), rng.uniform(0.12, 0.25)
    H = rng.uniform(0.8, 1.5)
    base = Box([L / 2, 0, T / 2], [L, W, T])
    wall = Box([T / 2, 0, H / 2], [T, W, H])
    parts: list[Implicit] = [base, wall]
    if rng.random() < 0.8:  # a triangular gusset: a rotated slab cut to the corner
        g = rng.uniform(0.3, 0.6) * min(L, H)
        slab = Box([0, 0, 0], [2 * g, 0.08, 2 * g]).rotate(rotation(_Y, np.pi / 4))
        parts.append(slab.translate([T, 0, T]) & Box([T + g / 2, 0, T + g / 2], [g, 0.08, g]))
    r = rng.uniform(0.05, 0.1)
    holes = _through_holes([(0.65 * L, -W / 4), (0.65 * L, W / 4)], r, 0.0, T)
    rot = rotation(_Y, np.pi / 2)  # wall holes along x
    holes += [
        h.rotate(rot, center=[0, 0, 0]).translate([0, 0, 0.65 * H])
        for h in _through_holes([(0.0, -W / 4), (0.0, W / 4)], r, -T, T)
    ]
    return Union(*parts) - Union(*holes)


def _flange(rng: np.random.Generator) -> Implicit:
    R, T = rng.uniform(0.8, 1.2), rng.uniform(0.12, 0.25)
    hub_r, hub_h = rng.uniform(0.3, 0.5) * R, rng.uniform(0.3, 0.7)
    body = Union(
        Cylinder([0, 0, 0], [0, 0, T], R), Cylinder([0, 0, T - 0.01], [0, 0, T + hub_h], hub_r)
    )
    bore = Cylinder([0, 0, -1.0], [0, 0, T + hub_h + 1.0], rng.uniform(0.4, 0.7) * hub_r)
    n = int(rng.integers(3, 9))
    centres = _ring(n, 0.5 * (hub_r + R), rng.uniform(0, 2 * np.pi / n))
    holes = _through_holes(centres, rng.uniform(0.05, 0.35) * (R - hub_r), 0.0, T)
    return body - Union(bore, *holes)


# -- further families ------------------------------------------------------------------
def _shaft(rng: np.random.Generator) -> Implicit:
    """Stepped shaft along x: 3-5 coaxial cylinders, a keyway slot in the widest step."""
    n = int(rng.integers(3, 6))
    lengths = rng.uniform(0.35, 0.9, n)
    lengths *= rng.uniform(2.4, 3.2) / lengths.sum()
    # A shoulder profile: radii rise towards the widest step and fall after it.
    peak = int(rng.integers(1, n - 1))
    radii = np.sort(rng.uniform(0.12, 0.32, n))[::-1]
    order = sorted(range(n), key=lambda i: abs(i - peak) + 0.1 * i)
    r = np.empty(n)
    r[order] = radii
    x = np.concatenate([[0.0], np.cumsum(lengths)]) - lengths.sum() / 2
    steps = [
        Cylinder([x[i] - (0.01 if i else 0), 0, 0], [x[i + 1], 0, 0], float(r[i])) for i in range(n)
    ]
    k = int(np.argmax(r))
    R, span = float(r[k]), float(lengths[k])
    depth, width = rng.uniform(0.25, 0.4) * R, rng.uniform(0.3, 0.5) * R
    key = Box([(x[k] + x[k + 1]) / 2, 0, R], [rng.uniform(0.5, 0.8) * span, width, 2 * depth])
    tools: list[Implicit] = [key]
    if rng.random() < 0.5:  # a centre drill in one end
        end = x[0]
        tools.append(Cylinder([end - 0.1, 0, 0], [end + 0.3, 0, 0], 0.3 * float(r[0])))
    return Union(*steps) - Union(*tools)


def _pipe_tee(rng: np.random.Generator) -> Implicit:
    """Hollow tee: a run along x and a (possibly reducing) branch up z, optional collars."""
    L, R = rng.uniform(1.6, 2.4), rng.uniform(0.3, 0.5)
    Rb, H = rng.uniform(0.65, 1.0) * R, rng.uniform(0.7, 1.3)
    wall = rng.uniform(0.1, 0.15)  # absolute, so the shell is a few grid cells thick
    body: list[Implicit] = [
        Cylinder([-L / 2, 0, 0], [L / 2, 0, 0], R),
        Cylinder([0, 0, 0], [0, 0, H], Rb),
    ]
    if rng.random() < 0.6:  # collars at the three ends
        c, t = rng.uniform(1.15, 1.35), rng.uniform(0.08, 0.15)
        body += [
            Cylinder([-L / 2, 0, 0], [-L / 2 + t, 0, 0], c * R),
            Cylinder([L / 2 - t, 0, 0], [L / 2, 0, 0], c * R),
            Cylinder([0, 0, H - t], [0, 0, H], c * Rb),
        ]
    bores = [
        Cylinder([-L / 2 - 0.5, 0, 0], [L / 2 + 0.5, 0, 0], max(R - wall, 0.4 * R)),
        Cylinder([0, 0, 0], [0, 0, H + 0.5], max(Rb - wall, 0.4 * Rb)),
    ]
    return Union(*body) - Union(*bores)


def _i_beam(rng: np.random.Generator) -> Implicit:
    """I-beam segment along x: two flanges and a web, optional lightening holes in the web."""
    L, H = rng.uniform(1.6, 2.4), rng.uniform(0.6, 1.0)
    B = rng.uniform(0.5, 0.8) * H
    tf, tw = rng.uniform(0.12, 0.2), rng.uniform(0.1, 0.16)
    beam = Union(
        Box([0, 0, tf / 2], [L, B, tf]),
        Box([0, 0, H - tf / 2], [L, B, tf]),
        Box([0, 0, H / 2], [L, tw, H - 2 * tf + 0.02]),
    )
    n = int(rng.integers(0, 4))
    if n == 0:
        return beam
    r = rng.uniform(0.2, 0.32) * (H - 2 * tf)
    xs = (np.arange(n) - (n - 1) / 2) * L / (n + 1)
    holes = [Cylinder([x, -1.0, H / 2], [x, 1.0, H / 2], r) for x in xs]
    return beam - Union(*holes)


def _gear_disc(rng: np.random.Generator) -> Implicit:
    """Spur-gear-like disc: teeth boxes around the rim, a bore with a keyway, a hub."""
    R, T = rng.uniform(0.6, 1.0), rng.uniform(0.15, 0.3)
    n = int(rng.integers(10, 25))
    h = rng.uniform(0.1, 0.18)  # tooth height
    w = rng.uniform(0.4, 0.55) * 2 * np.pi * R / n  # tooth width at the rim
    tooth = Box([R + h / 2 - 0.02, 0, T / 2], [h + 0.04, w, T])
    parts: list[Implicit] = [Cylinder([0, 0, 0], [0, 0, T], R)]
    parts += [tooth.rotate(rotation(_Z, 2 * np.pi * k / n)) for k in range(n)]
    bore_r = rng.uniform(0.15, 0.25) * R
    if rng.random() < 0.6:  # a hub on one face
        parts.append(Cylinder([0, 0, T - 0.01], [0, 0, T + rng.uniform(0.1, 0.3)], 2 * bore_r))
    tools: list[Implicit] = [
        Cylinder([0, 0, -1.0], [0, 0, 2.0], bore_r),
        Box([bore_r, 0, 0.5], [0.6 * bore_r, 0.5 * bore_r, 3.0]),
    ]
    m = int(rng.integers(0, 7))
    if m >= 3:  # lightening holes between bore and rim
        tools += _through_holes(
            _ring(m, 0.55 * R + 0.5 * bore_r, rng.uniform(0, np.pi)), 0.15 * R, 0.0, T
        )
    return Union(*parts) - Union(*tools)


def _hex_nut(rng: np.random.Generator) -> Implicit:
    """Hex nut: three rotated slabs intersected to a hexagonal prism, a bore, a washer face."""
    s, T = rng.uniform(0.8, 1.4), rng.uniform(0.35, 0.8)  # across flats, thickness
    slab = Box([0, 0, T / 2], [s, 2 * s, T])
    hexagon = slab & slab.rotate(rotation(_Z, np.pi / 3)) & slab.rotate(rotation(_Z, -np.pi / 3))
    c = 2 * s / np.sqrt(3)  # across corners: a tight box whatever the turn
    hexagon = hexagon.rotate(rotation(_Z, rng.uniform(0, np.pi / 3))) & Box(
        [0, 0, T / 2], [c, c, T]
    )
    body: Implicit = hexagon
    if rng.random() < 0.5:  # a washer face (flange) under the nut
        f = rng.uniform(0.08, 0.15)
        body = Union(hexagon.translate([0, 0, f - 0.01]), Cylinder([0, 0, 0], [0, 0, f], 0.55 * s))
    return body - Cylinder([0, 0, -1.0], [0, 0, T + 1.0], rng.uniform(0.22, 0.32) * s)


def _hinge(rng: np.random.Generator) -> Implicit:
    """Butt hinge: two drilled leaves on a knuckle along y, opened by a random angle."""
    a, b = rng.uniform(0.6, 1.0), rng.uniform(1.2, 2.0)  # leaf width (x), length (y)
    t = rng.uniform(0.1, 0.16)
    rk = rng.uniform(1.1, 1.6) * t
    n = int(rng.integers(2, 4))
    r = rng.uniform(0.05, 0.08)
    ys = (np.arange(n) - (n - 1) / 2) * b / n

    def leaf() -> Implicit:
        plate = Box([-a / 2 - rk / 2, 0, 0], [a + rk, b, t])
        return plate - Union(*_through_holes([(-a / 2 - rk / 2, y) for y in ys], r, -t, t))

    opening = rng.uniform(0.0, 0.4 * np.pi)
    knuckle = Cylinder([0, -b / 2, 0], [0, b / 2, 0], rk)
    pin = Cylinder([0, -b / 2 - 0.05, 0], [0, b / 2 + 0.05, 0], 0.6 * rk)
    return Union(leaf(), leaf().rotate(rotation(_Y, np.pi - opening)), knuckle, pin)


def _rib_plate(rng: np.random.Generator) -> Implicit:
    """Base plate stiffened by 2-5 parallel ribs along x, optional cross rib, corner holes."""
    L, W, T = rng.uniform(1.6, 2.4), rng.uniform(1.0, 1.6), rng.uniform(0.15, 0.25)
    n = int(rng.integers(2, 6))
    rt, rh = rng.uniform(0.1, 0.15), rng.uniform(0.2, 0.45)
    ys = (np.arange(n) - (n - 1) / 2) * (W - 0.3) / max(n - 1, 1)
    parts: list[Implicit] = [Box([0, 0, T / 2], [L, W, T])]
    parts += [Box([0, y, T + rh / 2 - 0.01], [0.9 * L, rt, rh + 0.02]) for y in ys]
    if rng.random() < 0.5:
        parts.append(Box([0, 0, T + rh / 2 - 0.01], [rt, W - 0.3, rh + 0.02]))
    r = rng.uniform(0.05, 0.08)
    corners = [(sx * (L / 2 - 0.1), sy * (W / 2 - 0.1)) for sx in (-1, 1) for sy in (-1, 1)]
    return Union(*parts) - Union(*_through_holes(corners, r, 0.0, T))


def _boss_plate(rng: np.random.Generator) -> Implicit:
    """Plate carrying a grid of tall drilled cylindrical bosses."""
    L, W, T = rng.uniform(1.6, 2.4), rng.uniform(1.0, 1.6), rng.uniform(0.15, 0.25)
    nx, ny = int(rng.integers(2, 4)), int(rng.integers(1, 3))
    xs = (np.arange(nx) - (nx - 1) / 2) * L / nx
    ys = (np.arange(ny) - (ny - 1) / 2) * W / ny
    R = rng.uniform(0.12, 0.2) * min(L / nx, 1.2 * W / ny)
    H = rng.uniform(0.3, 0.7)
    centres = [(float(x), float(y)) for x in xs for y in ys]
    bosses = [Cylinder([x, y, T - 0.01], [x, y, T + H], R) for x, y in centres]
    holes = _through_holes(centres, rng.uniform(0.35, 0.55) * R, 0.0, T + H)
    return Union(Box([0, 0, T / 2], [L, W, T]), *bosses) - Union(*holes)


def _handle(rng: np.random.Generator) -> Implicit:
    """Pull handle: a U of capsules (two legs, a grip) on drilled round feet."""
    w, h = rng.uniform(1.2, 2.0), rng.uniform(0.5, 1.0)
    r = rng.uniform(0.1, 0.16)
    splay = rng.uniform(0.0, 0.25) * h
    arch = rng.uniform(0.0, 0.2)
    feet = [np.array([s * w / 2, 0, 0.0]) for s in (-1, 1)]
    tops = [np.array([s * (w / 2 - splay), 0, h]) for s in (-1, 1)]
    mid = np.array([0, 0, h + arch])
    parts: list[Implicit] = [Capsule(f, t, r) for f, t in zip(feet, tops, strict=True)]
    parts += [Capsule(tops[0], mid, r), Capsule(mid, tops[1], r)]
    fr, ft = rng.uniform(1.8, 2.4) * r, rng.uniform(0.06, 0.12)
    parts += [Cylinder(f - [0, 0, ft], f + [0, 0, 0.01], fr) for f in feet]
    body = Union(*parts).translate([0, 0, ft])
    holes = [
        Cylinder([s * w / 2, 0, -0.5], [s * w / 2, 0, ft + 0.3 * h], 0.35 * r) for s in (-1, 1)
    ]
    return body - Union(*holes)  # blind screw holes up into the legs


BUILDERS: dict[str, Callable[[np.random.Generator], Implicit]] = {
    "plate": _plate,
    "bracket": _bracket,
    "flange": _flange,
    "shaft": _shaft,
    "pipe_tee": _pipe_tee,
    "i_beam": _i_beam,
    "gear_disc": _gear_disc,
    "hex_nut": _hex_nut,
    "hinge": _hinge,
    "rib_plate": _rib_plate,
    "boss_plate": _boss_plate,
    "handle": _handle,
}
