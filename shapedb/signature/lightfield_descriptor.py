"""The light field descriptor (Chen, Tian, Shen and Ouhyoung, Eurographics 2003), whatever draws it.

A shape is seen from the 20 vertices of a regular dodecahedron around it; opposite
vertices see mirror-image silhouettes, so a *light field* is 10 images. Each image is
described by the magnitudes of its Zernike moments up to ``zernike_order`` (36
numbers at order 10, invariant to turning and mirroring the image) and by the first
``fourier`` Fourier descriptors of its outer contour (the magnitudes of the Fourier
transform of the centroid distance, divided by its mean). A shape has ``n_fields``
light fields, from dodecahedra turned in fixed, seeded ways. The distance between two
shapes is the smallest, over every pair of their light fields and over the 60
rotations of the dodecahedron (which permute the 10 views), of the summed L1 distances
between corresponding images (Chen et al.'s Eq. 1-2). It is not an L1 distance between
vectors: it belongs to an exact re-ranking stage, not to a vector index.

This module holds what does not depend on where the images come from: the
dodecahedron, its rotations, the image features and the distance.
:mod:`shapedb.signature.lightfield` renders the images of a ball union or of a field's inside;
``bench/lightfield.py`` those of a mesh's surface.
"""

from __future__ import annotations

import functools
from math import factorial

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from shapedb.config.core import LightFieldConfig

__all__ = [
    "dodecahedron_views",
    "dodecahedron_rotations",
    "view_permutations",
    "field_rotations",
    "field_directions",
    "image_axes",
    "zernike_magnitudes",
    "silhouette_features",
    "light_field_dim",
    "light_field_distance",
    "silhouette_dim",
]

FloatArray = NDArray[np.float64]
PHI = (1.0 + 5.0**0.5) / 2.0


# --------------------------------------------------------------------------------------
# The dodecahedron, its rotations and the light fields' directions
# --------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def _vertices() -> FloatArray:
    """(20, 3) unit vertices of a regular dodecahedron; vertex ``i + 10`` is ``-vertex i``."""
    a, b = 1.0 / PHI, PHI
    half = [(1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1),
            (0, a, b), (0, a, -b), (a, b, 0), (a, -b, 0), (b, 0, a), (b, 0, -a)]  # fmt: skip
    v = np.asarray(half, dtype=np.float64)
    v = np.vstack([v, -v])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def dodecahedron_views() -> FloatArray:
    """(10, 3) unit view directions: one vertex of each opposite pair of a dodecahedron."""
    return _vertices()[:10].copy()


@functools.lru_cache(maxsize=1)
def dodecahedron_rotations() -> FloatArray:
    """(60, 3, 3) the rotations that map the dodecahedron onto itself (identity first)."""
    v = _vertices()
    d = v @ v.T
    near = np.max(d[~np.eye(20, dtype=bool)])
    nbrs = [np.flatnonzero(np.isclose(d[i], near)) for i in range(20)]
    a0, b0 = v[0], v[nbrs[0][0]]
    src = np.stack([a0, b0, np.cross(a0, b0)])
    out = []
    for i in range(20):
        for j in nbrs[i]:
            dst = np.stack([v[i], v[j], np.cross(v[i], v[j])])
            out.append(np.linalg.solve(src, dst).T)  # r @ src[k] = dst[k]
    rots = np.asarray(out)
    order = np.argsort([np.abs(r - np.eye(3)).sum() > 1e-9 for r in rots], kind="stable")
    return rots[order]


@functools.lru_cache(maxsize=1)
def view_permutations() -> NDArray[np.int64]:
    """(60, 10) int: rotation ``r`` takes view ``v`` to view ``perm[r, v]`` (up to its opposite)."""
    views = _vertices()[:10]
    perm = np.empty((60, 10), dtype=np.int64)
    for k, r in enumerate(dodecahedron_rotations()):
        perm[k] = np.argmax(np.abs((views @ r.T) @ views.T), axis=1)
    return perm


def field_rotations(n: int, seed: int) -> FloatArray:
    """(n, 3, 3) the light fields' turns: the identity, then seeded uniform random rotations."""
    rng = np.random.default_rng(seed + 7919)
    out = [np.eye(3)]
    while len(out) < n:
        q, r = np.linalg.qr(rng.normal(size=(3, 3)))
        q = q * np.sign(np.diag(r))
        out.append(q if np.linalg.det(q) > 0 else -q)
    return np.asarray(out[:n])


def field_directions(n_fields: int, seed: int) -> FloatArray:
    """(n_fields * 10, 3) unit view directions, field-major (10 per light field)."""
    views = dodecahedron_views()
    return np.concatenate([views @ rot.T for rot in field_rotations(n_fields, seed)])


def image_axes(directions: ArrayLike) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Orthonormal image axes ``(u, w)``, each (m, 3) float32, of unit view directions (m, 3).

    ``(u, w, d)`` is right-handed; image pixel ``(row, col)`` lies along ``w`` and ``u``.
    """
    d = np.asarray(directions, dtype=np.float32).reshape(-1, 3)
    helper = np.where(np.abs(d[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    u = np.cross(d, helper.astype(np.float32))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u, np.cross(d, u)


# --------------------------------------------------------------------------------------
# Image features
# --------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=8)
def _zernike_basis(resolution: int, order: int) -> NDArray[np.complex128]:
    """(moments, resolution**2) conjugate Zernike polynomials on the pixel centres (unit disc)."""
    c = (np.arange(resolution) + 0.5) / resolution * 2.0 - 1.0
    x, y = np.meshgrid(c, c)
    rho, theta = np.hypot(x, y), np.arctan2(y, x)
    disc = rho <= 1.0
    rows = []
    for n in range(order + 1):
        for m in range(n % 2, n + 1, 2):
            radial = np.zeros_like(rho)
            for s in range((n - m) // 2 + 1):
                coef = (-1) ** s * factorial(n - s)
                coef /= factorial(s) * factorial((n + m) // 2 - s) * factorial((n - m) // 2 - s)
                radial += coef * rho ** (n - 2 * s)
            v = radial * np.exp(-1j * m * theta) * disc
            rows.append((n + 1) / np.pi * v.ravel() * (2.0 / resolution) ** 2)
    return np.asarray(rows)


def zernike_magnitudes(images: ArrayLike, order: int) -> FloatArray:
    """Zernike moment magnitudes ``|A_nm|`` (n <= order, m >= 0, n - m even) of images.

    Parameters
    ----------
    images : (k, r, r) bool or float
        Images on [-1, 1]^2; pixels outside the unit disc are ignored.
    order : int
        Largest order n.

    Returns
    -------
    (k, z) float64
        Ordered by n, then m; a filled unit disc has ``|A_00| = 1`` and every moment with
        ``m > 0`` zero (up to pixel sampling).
    """
    img = np.asarray(images, dtype=np.float64)
    k, r = img.shape[0], img.shape[1]
    return np.abs(img.reshape(k, -1) @ _zernike_basis(r, order).T)


def _contour_fourier(flat: FloatArray, r: int, fourier: int, angles: int) -> FloatArray:
    """(k, fourier) Fourier magnitudes 1..fourier of the centroid distance / its mean."""
    k = len(flat)
    c = (np.arange(r) + 0.5) / r * 2.0 - 1.0
    x, y = np.meshgrid(c, c)
    count = np.maximum(flat.sum(axis=1), 1.0)
    cx, cy = flat @ x.ravel() / count, flat @ y.ravel() / count
    row, pix = np.nonzero(flat)
    dx, dy = x.ravel()[pix] - cx[row], y.ravel()[pix] - cy[row]
    ang = ((np.arctan2(dy, dx) + np.pi) / (2 * np.pi) * angles).astype(np.int64) % angles
    prof = np.zeros(k * angles)
    # per angle bin, the farthest pixel (its far edge): the outer contour
    np.maximum.at(prof, row * angles + ang, np.hypot(dx, dy) + 0.5 * 2.0 / r)
    spec = np.abs(np.fft.rfft(prof.reshape(k, angles), axis=1))
    return spec[:, 1 : fourier + 1] / np.maximum(spec[:, :1], 1e-12)


def silhouette_features(images: ArrayLike, config: LightFieldConfig | None = None) -> FloatArray:
    """Zernike and Fourier descriptors of silhouettes.

    Parameters
    ----------
    images : (k, r, r) bool
        Silhouettes on [-1, 1]^2 (any square resolution ``r``).
    config : LightFieldConfig, optional
        Orders and weights (``depth_weight`` is not used here).

    Returns
    -------
    (k, z + config.fourier) float64
        Per image: the ``z`` :func:`zernike_magnitudes`, then the Fourier magnitudes
        1..fourier of the centroid distance divided by its mean, times
        ``config.fourier_weight``; an empty image gives zeros.
    """
    cfg = config or LightFieldConfig()
    img = np.asarray(images, dtype=bool)
    k, r = img.shape[0], img.shape[1]
    flat = img.reshape(k, -1).astype(np.float64)
    zern = np.abs(flat @ _zernike_basis(r, cfg.zernike_order).T)
    four = _contour_fourier(flat, r, cfg.fourier, cfg.angles)
    return np.hstack([zern, cfg.fourier_weight * four])


def _zernike_count(order: int) -> int:
    return sum(1 for n in range(order + 1) for _ in range(n % 2, n + 1, 2))


def silhouette_dim(config: LightFieldConfig | None = None) -> int:
    """Numbers of :func:`silhouette_features` per image under ``config`` (Zernike, Fourier):
    the leading part of each view of :func:`ball_light_field`."""
    cfg = config or LightFieldConfig()
    return _zernike_count(cfg.zernike_order) + cfg.fourier


def light_field_dim(config: LightFieldConfig | None = None) -> int:
    """Numbers per view of :func:`ball_light_field` under ``config``."""
    cfg = config or LightFieldConfig()
    z = _zernike_count(cfg.zernike_order)
    return z + cfg.fourier + (2 * z if cfg.depth_weight > 0 else 0)


# --------------------------------------------------------------------------------------
# The distance
# --------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def _permutations() -> NDArray[np.int64]:
    """(60, 10) int64: rotation r takes view v to view ``perm[r, v]``."""
    return np.ascontiguousarray(view_permutations(), dtype=np.int64)


@njit(cache=True, fastmath=True)
def _nearest_turn(a: FloatArray, b: FloatArray, perm: NDArray[np.int64]) -> FloatArray:
    """(m,) per shape of ``b`` (m, fb * 10, d) the least, over light-field pairs and the 60
    rotations ``perm`` (60, 10), of the summed L1 distances of corresponding views of ``a``
    (fa * 10, d) and it: one shape's 10 x 10 view distances at a time, in cache."""
    fa, d = a.shape[0] // 10, a.shape[1]
    m, fb = b.shape[0], b.shape[1] // 10
    out = np.empty(m)
    views = np.empty((fa * 10, fb * 10))
    for j in range(m):
        for u in range(fa * 10):
            for v in range(fb * 10):
                s = 0.0
                for t in range(d):
                    s += abs(a[u, t] - b[j, v, t])
                views[u, v] = s
        best = np.inf
        for p in range(fa):
            for q in range(fb):
                for r in range(60):
                    s = 0.0
                    for u in range(10):
                        s += views[p * 10 + u, q * 10 + perm[r, u]]
                    best = min(best, s)
        out[j] = best
    return out


def light_field_distance(descriptors: ArrayLike, others: ArrayLike | None = None) -> FloatArray:
    """Light field distances between shapes: (n, m) float64.

    Parameters
    ----------
    descriptors : (n, fields, 10, d) float
        Query shapes' light fields (e.g. :func:`ball_light_field`).
    others : (m, fields', 10, d) float, optional
        Candidate shapes' light fields; defaults to ``descriptors``.

    Returns
    -------
    (n, m) float64
        For each pair, the minimum over light-field pairs and the 60 dodecahedron
        rotations of the summed L1 distances of corresponding views; symmetric, 0 on
        the diagonal. Without ``others`` only the upper triangle is computed.

    Raises
    ------
    ValueError
        If the arrays are not (count, fields, 10, d) with the same ``d``.
    """
    a = np.asarray(descriptors, dtype=np.float64)
    b = a if others is None else np.asarray(others, dtype=np.float64)
    if (
        a.ndim != 4
        or b.ndim != 4
        or a.shape[2] != 10
        or b.shape[2] != 10
        or a.shape[3] != b.shape[3]
    ):
        raise ValueError(f"light fields of shapes {a.shape} and {b.shape} do not match")
    n, fa, _, d = a.shape
    m, fb = b.shape[0], b.shape[1]
    perm = _permutations()
    af = np.ascontiguousarray(a.reshape(n, fa * 10, d))
    bf = np.ascontiguousarray(b.reshape(m, fb * 10, d))
    symmetric = others is None
    out = np.zeros((n, m))
    for i in range(n):
        start = i if symmetric else 0
        out[i, start:] = _nearest_turn(af[i], bf[start:], perm)
    if symmetric:
        out = np.triu(out) + np.triu(out, 1).T
    return out
