"""Mesh parts the generated web-like sets are assembled from.

Each part is a ``(vertices (v, 3) float, faces (f, 3) int)`` pair in its own index
space; the generators (:mod:`bench.sets.generic_shapes`, :mod:`bench.sets.web_shapes`)
concatenate them into one triangle soup without merging, as web models are built.
Closed parts: :func:`box`, :func:`rod`, :func:`ellipsoid`, :func:`revolve` with both
caps; open parts: :func:`quad` / :func:`hquad` (zero-thickness sheets) and
:func:`revolve` without caps (tubes, shades, dishes). Lengths are in model units.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "V", "F", "Part", "Rng", "box", "quad", "hquad", "revolve", "rod", "ellipsoid", "place",
    "sheet", "prism", "rotation", "transform",
]  # fmt: skip

V = NDArray[np.float64]
F = NDArray[np.int64]
Part = tuple[V, F]
Rng = np.random.Generator

_BOX_F = np.array(
    [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
     [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]],
)  # fmt: skip


def box(c: tuple[float, ...] | V, s: tuple[float, ...] | V) -> Part:
    """A closed box centred at ``c`` with full sizes ``s``."""
    c, h = np.asarray(c, float), 0.5 * np.asarray(s, float)
    sx = np.array([-1, 1, 1, -1, -1, 1, 1, -1])
    sy = np.array([-1, -1, 1, 1, -1, -1, 1, 1])
    sz = np.array([-1, -1, -1, -1, 1, 1, 1, 1])
    v = c + np.stack([sx * h[0], sy * h[1], sz * h[2]], axis=1)
    return v, _BOX_F.copy()


def quad(c: tuple[float, ...] | V, a: tuple[float, ...] | V, b: tuple[float, ...] | V) -> Part:
    """A zero-thickness rectangle ``c + s a + t b``, s, t in [-1, 1]."""
    c, a, b = (np.asarray(x, float) for x in (c, a, b))
    v = np.stack([c - a - b, c + a - b, c + a + b, c - a + b])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def hquad(c: tuple[float, ...], sx: float, sy: float) -> Part:
    """A horizontal sheet of full sizes ``sx``, ``sy``."""
    return quad(c, (sx / 2, 0, 0), (0, sy / 2, 0))


def revolve(
    z: V, r: V, *, n: int = 16, bottom: bool = True, top: bool = False,
    c: tuple[float, float] = (0.0, 0.0),
) -> Part:  # fmt: skip
    """Surface of revolution about the vertical through ``c``: radii ``r`` at heights ``z``."""
    z, r = np.asarray(z, float), np.asarray(r, float)
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(t), np.sin(t)], axis=1)
    v = [np.column_stack([c[0] + ri * ring[:, 0], c[1] + ri * ring[:, 1], np.full(n, zi)])
         for zi, ri in zip(z, r, strict=True)]  # fmt: skip
    verts = np.concatenate(v)
    faces = []
    for k in range(len(z) - 1):
        for j in range(n):
            a, b = k * n + j, k * n + (j + 1) % n
            faces += [[a, b, b + n], [a, b + n, a + n]]
    for cap, k in ((bottom, 0), (top, len(z) - 1)):
        if cap:
            centre = len(verts)
            verts = np.vstack([verts, [c[0], c[1], z[k]]])
            faces += [[centre, k * n + (j + 1) % n, k * n + j] for j in range(n)]
    return verts, np.asarray(faces)


def rod(p0: tuple[float, ...] | V, p1: tuple[float, ...] | V, r: float, n: int = 8) -> Part:
    """A capped cylinder from ``p0`` to ``p1`` of radius ``r``."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    length = float(np.linalg.norm(p1 - p0))
    v, f = revolve(np.array([0.0, length]), np.array([r, r]), n=n, top=True)
    return place(v, p0, (p1 - p0) / max(length, 1e-12)), f


def ellipsoid(c: tuple[float, ...] | V, radii: tuple[float, ...] | V) -> Part:
    """A closed ellipsoid (an icosphere, 80 faces, scaled)."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=1)
    return np.asarray(s.vertices) * np.asarray(radii, float) + np.asarray(c, float), np.asarray(
        s.faces, dtype=np.int64
    )


def place(v: V, origin: V, axis: V) -> V:
    """Map local z to ``axis`` (unit) and translate by ``origin``."""
    z = np.array([0.0, 0.0, 1.0])
    k = np.cross(z, axis)
    s, c = float(np.linalg.norm(k)), float(z @ axis)
    if s < 1e-12:
        rot = np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    else:
        k /= s
        kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        rot = np.eye(3) + s * kx + (1 - c) * kx @ kx
    return np.asarray(v @ rot.T + origin)


def sheet(points: ArrayLike) -> Part:
    """A zero-thickness planar polygon (a triangle fan over ``points`` (k, 3), k >= 3)."""
    v = np.asarray(points, dtype=float)
    k = len(v)
    return v, np.array([[0, i, i + 1] for i in range(1, k - 1)], dtype=np.int64)


def prism(outline: V, y0: float, y1: float, *, caps: bool = True) -> Part:
    """A polygon ``outline`` (k, 2) in the x-z plane extruded along y from ``y0`` to ``y1``.

    The side walls are always there; ``caps`` closes both ends with fans (a closed
    solid for a convex or star-shaped outline about its first point).
    """
    o = np.asarray(outline, dtype=float)
    k = len(o)
    a = np.column_stack([o[:, 0], np.full(k, y0), o[:, 1]])
    b = np.column_stack([o[:, 0], np.full(k, y1), o[:, 1]])
    v = np.vstack([a, b])
    faces = []
    for i in range(k):
        j = (i + 1) % k
        faces += [[i, j, k + j], [i, k + j, k + i]]
    if caps:
        faces += [[0, i + 1, i] for i in range(1, k - 1)]
        faces += [[k, k + i, k + i + 1] for i in range(1, k - 1)]
    return v, np.asarray(faces, dtype=np.int64)


def rotation(axis: int, angle: float) -> NDArray[np.float64]:
    """(3, 3) rotation by ``angle`` radians about coordinate axis ``axis`` (0 x, 1 y, 2 z)."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def transform(
    part: Part, rot: NDArray[np.float64] | None = None, shift: V | tuple[float, ...] = (0, 0, 0)
) -> Part:
    """``part`` rotated by ``rot`` (3, 3) about the origin, then translated by ``shift``."""
    v, f = part
    if rot is not None:
        v = v @ np.asarray(rot, dtype=float).T
    return np.asarray(v + np.asarray(shift, dtype=float)), f
