"""The light field descriptor (Chen, Tian, Shen and Ouhyoung, Eurographics 2003), in numpy.

A model is seen from the 20 vertices of a regular dodecahedron around it; opposite
vertices see mirror-image silhouettes, so a *light field* is 10 silhouettes. Each
silhouette is described by the magnitudes of its Zernike moments up to order 10
(36 numbers, in-plane-rotation invariant) and by the first 10 Fourier descriptors of
its outer contour (the magnitudes of the Fourier transform of the centroid distance,
divided by the mean distance). A model has ``n_fields`` light fields from dodecahedra
turned in fixed, spread-out ways. The distance between two models is the smallest,
over every pair of their light fields and over the 60 rotations of the dodecahedron
(which permute the 10 views), of the summed L1 distances between corresponding
silhouettes (Chen et al.'s Eq. 1-2).

Silhouettes are rendered by dense surface splats: ``n_points`` points sampled by area
on the triangles (plus the vertices), scaled into the unit sphere about their mean,
projected orthographically onto a ``resolution`` x ``resolution`` image of the
unit disc and closed morphologically (one pixel), so that a surface seen face-on
leaves no holes while thin rods and sheets seen edge-on stay visible. Orientation,
connectivity and watertightness of the mesh do not matter. Chen et al. render at
256 x 256 and quantise each coefficient to 8 bits; here the silhouettes are smaller
and the coefficients stay floats.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bench.baselines import sample_surface

__all__ = [
    "LFDConfig",
    "dodecahedron_views",
    "dodecahedron_rotations",
    "view_permutations",
    "render_silhouettes",
    "silhouette_features",
    "lfd_descriptor",
    "lfd_distance",
    "lfd_similarity",
]

PHI = (1.0 + 5.0**0.5) / 2.0


@dataclass(frozen=True)
class LFDConfig:
    """Parameters of the light field descriptor.

    Attributes
    ----------
    n_fields : int
        Light fields per model (Chen et al.: 10).
    resolution : int
        Silhouette image side, pixels (Chen et al.: 256).
    n_points : int
        Surface samples splatted into each silhouette.
    zernike_order : int
        Largest Zernike order (Chen et al.: 10, 35-36 moments).
    fourier : int
        Fourier descriptors per silhouette (Chen et al.: 10).
    angles : int
        Samples of the centroid-distance function around the contour.
    fourier_weight : float
        Weight of the Fourier block against the Zernike block in the L1 distance.
    seed : int
        Seed of the surface sampling and of the light fields' rotations.
    """

    n_fields: int = 10
    resolution: int = 64
    n_points: int = 40000
    zernike_order: int = 10
    fourier: int = 10
    angles: int = 64
    fourier_weight: float = 1.0
    seed: int = 0


# --------------------------------------------------------------------------------------
# The dodecahedron and its rotations
# --------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def _vertices() -> NDArray[np.float64]:
    """(20, 3) unit vertices of a regular dodecahedron; vertex ``i + 10`` is ``-vertex i``."""
    a, b = 1.0 / PHI, PHI
    half = [(1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1),
            (0, a, b), (0, a, -b), (a, b, 0), (a, -b, 0), (b, 0, a), (b, 0, -a)]  # fmt: skip
    v = np.asarray(half, dtype=np.float64)
    v = np.vstack([v, -v])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def dodecahedron_views() -> NDArray[np.float64]:
    """(10, 3) unit view directions: one vertex of each opposite pair of a dodecahedron."""
    return _vertices()[:10].copy()


@functools.lru_cache(maxsize=1)
def dodecahedron_rotations() -> NDArray[np.float64]:
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
            r = np.linalg.solve(src, dst).T  # r @ src[k] = dst[k]
            out.append(r)
    rots = np.asarray(out)
    order = np.argsort([np.abs(r - np.eye(3)).sum() > 1e-9 for r in rots], kind="stable")
    return rots[order]


@functools.lru_cache(maxsize=1)
def view_permutations() -> NDArray[np.int64]:
    """(60, 10) int: rotation ``r`` takes view ``v`` to view ``perm[r, v]`` (up to its opposite)."""
    v = _vertices()
    views = v[:10]
    perm = np.empty((60, 10), dtype=np.int64)
    for k, r in enumerate(dodecahedron_rotations()):
        img = views @ r.T
        perm[k] = np.argmax(np.abs(img @ views.T), axis=1)
    return perm


def _field_rotations(n: int, seed: int) -> NDArray[np.float64]:
    """(n, 3, 3) the light fields' turns: identity, then seeded uniformly random rotations."""
    rng = np.random.default_rng(seed + 7919)
    out = [np.eye(3)]
    while len(out) < n:
        q, r = np.linalg.qr(rng.normal(size=(3, 3)))
        q = q * np.sign(np.diag(r))
        out.append(q if np.linalg.det(q) > 0 else -q)
    return np.asarray(out[:n])


# --------------------------------------------------------------------------------------
# Silhouettes and their features
# --------------------------------------------------------------------------------------


def _surface_points(
    vertices: ArrayLike, faces: ArrayLike, n: int, seed: int, resolution: int
) -> NDArray[np.float32]:
    """Surface samples in the unit sphere about their mean, one per occupied half-pixel voxel.

    ``n`` area-weighted samples plus the used vertices; samples that share a cube of
    half a pixel's side (1 / ``resolution``) are merged to that cube's centre, which
    moves no silhouette pixel by more than about half a pixel.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    p = sample_surface(v, f, n, rng=np.random.default_rng(seed))
    p = np.vstack([p, v[np.unique(f)]])
    p = p - p[:n].mean(axis=0)
    radius = float(np.linalg.norm(p, axis=1).max())
    if not radius > 0:
        raise ValueError("the mesh is a single point: no silhouette")
    side = 2 * resolution + 2  # cell indices lie in [-resolution, resolution]
    cells = np.floor(p / radius * resolution).astype(np.int64) + resolution
    key = np.unique((cells[:, 0] * side + cells[:, 1]) * side + cells[:, 2])
    cells = np.stack([key // (side * side), key // side % side, key % side], axis=1) - resolution
    return ((cells + 0.5) / resolution).astype(np.float32)


def render_silhouettes(
    points: ArrayLike, directions: ArrayLike, resolution: int
) -> NDArray[np.bool_]:
    """Orthographic silhouettes of a point set in the unit sphere.

    Parameters
    ----------
    points : (k, 3) float
        Dense surface samples, inside the unit sphere.
    directions : (m, 3) float
        Unit view directions.
    resolution : int
        Image side, pixels; the image spans [-1, 1]^2.

    Returns
    -------
    (m, resolution, resolution) bool
        One closed (3 x 3) silhouette per direction.
    """
    from scipy import ndimage

    p = np.asarray(points, dtype=np.float32)
    d = np.asarray(directions, dtype=np.float32)
    # an orthonormal image basis (u, w) per direction
    helper = np.where(np.abs(d[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]]).astype(
        np.float32
    )
    u = np.cross(d, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(d, u)
    half = np.float32(0.5 * resolution)
    px = np.clip(((p @ u.T + 1.0) * half).astype(np.int32), 0, resolution - 1)
    py = np.clip(((p @ w.T + 1.0) * half).astype(np.int32), 0, resolution - 1)
    m = len(d)
    flat = (np.arange(m, dtype=np.int32)[None, :] * resolution + py) * resolution + px
    img = np.zeros(m * resolution * resolution, dtype=bool)
    img[flat.ravel()] = True
    img = img.reshape(m, resolution, resolution)
    pad = np.pad(img, ((0, 0), (1, 1), (1, 1)))
    ball = np.zeros((1, 3, 3), dtype=bool)
    ball[0] = True
    closed = ndimage.binary_erosion(ndimage.binary_dilation(pad, ball), ball)
    return np.asarray(closed[:, 1:-1, 1:-1] | img)


@functools.lru_cache(maxsize=4)
def _zernike_basis(resolution: int, order: int) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """(moments, resolution**2) conjugate Zernike polynomials on the pixel centres, and the disc."""
    from math import factorial

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
    return np.asarray(rows), disc


def silhouette_features(images: ArrayLike, config: LFDConfig | None = None) -> NDArray[np.float64]:
    """Zernike and Fourier descriptors of silhouettes.

    Parameters
    ----------
    images : (m, r, r) bool
        Silhouettes on [-1, 1]^2 (r = ``config.resolution``).
    config : LFDConfig, optional
        Orders and weights.

    Returns
    -------
    (m, z + config.fourier) float64
        Per image: the ``z`` Zernike magnitudes ``|A_nm|`` (n <= order, m >= 0,
        n - m even), then the Fourier magnitudes 1..fourier of the centroid distance
        divided by its mean, times ``config.fourier_weight``; an empty image gives zeros.
    """
    cfg = config or LFDConfig()
    img = np.asarray(images, dtype=bool)
    m, r = img.shape[0], img.shape[1]
    basis, _ = _zernike_basis(r, cfg.zernike_order)
    flat = img.reshape(m, -1).astype(np.float64)
    zern = np.abs(flat @ basis.T)
    # centroid distance of the outer contour: per angle bin, the farthest pixel
    c = (np.arange(r) + 0.5) / r * 2.0 - 1.0
    x, y = np.meshgrid(c, c)
    count = np.maximum(flat.sum(axis=1), 1.0)
    cx, cy = flat @ x.ravel() / count, flat @ y.ravel() / count
    k, pix = np.nonzero(flat)
    dx, dy = x.ravel()[pix] - cx[k], y.ravel()[pix] - cy[k]
    ang = ((np.arctan2(dy, dx) + np.pi) / (2 * np.pi) * cfg.angles).astype(np.int64) % cfg.angles
    prof = np.zeros(m * cfg.angles)
    np.maximum.at(prof, k * cfg.angles + ang, np.hypot(dx, dy) + 0.5 * 2.0 / r)
    prof = prof.reshape(m, cfg.angles)
    spec = np.abs(np.fft.rfft(prof, axis=1))
    four = spec[:, 1 : cfg.fourier + 1] / np.maximum(spec[:, :1], 1e-12)
    return np.hstack([zern, cfg.fourier_weight * four])


def lfd_descriptor(
    vertices: ArrayLike, faces: ArrayLike, config: LFDConfig | None = None
) -> NDArray[np.float64]:
    """The light fields of a triangle mesh: (n_fields, 10, features) float64.

    Parameters
    ----------
    vertices : (v, 3) float
        Vertex positions.
    faces : (f, 3) int
        Triangles (a soup is fine: orientation and connectivity are not used).
    config : LFDConfig, optional
        Fields, resolution, sampling and feature orders.

    Returns
    -------
    (config.n_fields, 10, features) float64
        Per light field, per dodecahedron view (:func:`dodecahedron_views` turned by
        the field's rotation), the :func:`silhouette_features`. Invariant to
        translation and scale; rotations are handled by :func:`lfd_distance`.

    Raises
    ------
    ValueError
        For a mesh of zero area.
    """
    cfg = config or LFDConfig()
    p = _surface_points(vertices, faces, cfg.n_points, cfg.seed, cfg.resolution)
    views = dodecahedron_views()
    dirs = np.concatenate([views @ rot.T for rot in _field_rotations(cfg.n_fields, cfg.seed)])
    feats = silhouette_features(render_silhouettes(p, dirs, cfg.resolution), cfg)
    return feats.reshape(cfg.n_fields, 10, -1)


@functools.lru_cache(maxsize=1)
def _permutation_matrix() -> NDArray[np.float64]:
    """(100, 60): column r sums the view distances D[v, perm[r, v]] of a flattened (10, 10) D."""
    perm = view_permutations()
    out = np.zeros((100, 60))
    for r in range(60):
        out[np.arange(10) * 10 + perm[r], r] = 1.0
    return out


def lfd_distance(
    descriptors: ArrayLike, others: ArrayLike | None = None, *, chunk: int = 64
) -> NDArray[np.float64]:
    """Light field distances between models: (n, m) float64.

    Parameters
    ----------
    descriptors : (n, fields, 10, d) float
        Query models' :func:`lfd_descriptor`.
    others : (m, fields', 10, d) float, optional
        Database models; defaults to ``descriptors``.
    chunk : int
        Database models compared at once (bounds memory).

    Returns
    -------
    (n, m) float64
        For each pair, the minimum over light-field pairs and the 60 dodecahedron
        rotations of the summed L1 distances of corresponding silhouettes. Without
        ``others`` only the upper triangle is computed (the distance is symmetric:
        the rotations form a group).
    """
    from scipy.spatial.distance import cdist

    a = np.asarray(descriptors, dtype=np.float64)
    b = a if others is None else np.asarray(others, dtype=np.float64)
    n, fa, nv, d = a.shape
    m, fb = b.shape[0], b.shape[1]
    if nv != 10 or b.shape[2] != 10 or b.shape[3] != d:
        raise ValueError(f"light fields of shapes {a.shape} and {b.shape} do not match")
    perm = _permutation_matrix()
    bf = b.reshape(m * fb * 10, d)
    symmetric = others is None  # the distance is symmetric: compute the upper triangle
    out = np.empty((n, m))
    for i in range(n):
        for s in range(i if symmetric else 0, m, chunk):
            e = min(s + chunk, m)
            dist = cdist(a[i].reshape(fa * 10, d), bf[s * fb * 10 : e * fb * 10], "cityblock")
            dist = dist.reshape(fa, 10, e - s, fb, 10).transpose(2, 0, 3, 1, 4)
            sums = dist.reshape(e - s, fa * fb, 100) @ perm
            out[i, s:e] = sums.reshape(e - s, -1).min(axis=1)
    if symmetric:
        upper = np.triu(out)
        out = upper + np.triu(out, 1).T
    return out


def lfd_similarity(descriptors: ArrayLike, others: ArrayLike | None = None) -> NDArray[np.float64]:
    """Similarity ``-`` :func:`lfd_distance` (larger is more similar): (n, m) float64."""
    return -lfd_distance(descriptors, others)
