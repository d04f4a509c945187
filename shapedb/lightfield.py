"""The light field descriptor (Chen, Tian, Shen and Ouhyoung, Eurographics 2003), from balls.

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

This module holds what does not depend on where the images come from (the
dodecahedron, its rotations, the image features, the descriptor of a stack of
images, the distance), and renders the images of a ball union, which keeps the
descriptor representation-agnostic: seen along ``d``, a ball of centre ``c`` and
radius ``r`` projects to a disc of radius ``r`` about ``c``'s projection, its front at
height ``c . d + sqrt(r^2 - rho^2)``. The balls are centred on their volume centroid
(:func:`shapedb.union.centred_balls`) and scaled so that the farthest ball's far side
lies on the unit sphere; images span the unit disc, a pixel is covered when its
centre lies within ``r`` plus half a pixel of a disc's centre (so that balls thinner
than a pixel, as on thickened sheets, stay visible). With ``depth_weight > 0`` each
view also carries the Zernike magnitudes of its front and back depth images,
``(h + 1) / 2`` where covered (``h`` the nearest front's height, unit sphere), 0
elsewhere; opposite views swap front and back, so the two enter as their sum and
absolute difference.

Silhouettes of other sources (surface splats of a mesh, ``bench/lightfield.py``) use
:func:`silhouette_features`, :func:`field_directions` and :func:`light_field_distance`
the same way.
"""

from __future__ import annotations

import functools
from dataclasses import replace
from math import factorial
from typing import TYPE_CHECKING

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from shapedb.config import LightFieldConfig
from shapedb.union import centred_balls

if TYPE_CHECKING:
    from shapedb.inside import Inside
    from shapedb.mdbd import Decomposition

__all__ = [
    "dodecahedron_views",
    "dodecahedron_rotations",
    "view_permutations",
    "field_rotations",
    "field_directions",
    "image_axes",
    "zernike_magnitudes",
    "silhouette_features",
    "render_discs",
    "ball_light_field",
    "record_light_field",
    "inside_light_field",
    "decomposition_light_field",
    "light_field_dim",
    "light_field_distance",
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


def light_field_dim(config: LightFieldConfig | None = None) -> int:
    """Numbers per view of :func:`ball_light_field` under ``config``."""
    cfg = config or LightFieldConfig()
    z = sum(1 for n in range(cfg.zernike_order + 1) for _ in range(n % 2, n + 1, 2))
    return z + cfg.fourier + (2 * z if cfg.depth_weight > 0 else 0)


# --------------------------------------------------------------------------------------
# Images of a ball union
# --------------------------------------------------------------------------------------


@njit(cache=True)
def _splat_discs(
    x: NDArray[np.float32],
    r: NDArray[np.float32],
    edges: NDArray[np.int64],
    u: NDArray[np.float32],
    w: NDArray[np.float32],
    d: NDArray[np.float32],
    res: int,
    depth: bool,
    grow: float,
) -> tuple[NDArray[np.bool_], NDArray[np.float32], NDArray[np.float32]]:
    m, n = u.shape[0], x.shape[0]
    sil = np.zeros((m, res, res), dtype=np.bool_)
    shape = (m, res, res) if depth else (1, 1, 1)
    front = np.full(shape, -2.0, dtype=np.float32)
    back = np.full(shape, -2.0, dtype=np.float32)
    half = np.float32(0.5 * res)
    slack = np.float32(1.0 / res + grow)  # half a pixel (plus the growth), image units
    pu = np.empty(n, dtype=np.float32)
    pw = np.empty(n, dtype=np.float32)
    for k in range(m):
        for i in range(n):
            pu[i] = x[i, 0] * u[k, 0] + x[i, 1] * u[k, 1] + x[i, 2] * u[k, 2]
            pw[i] = x[i, 0] * w[k, 0] + x[i, 1] * w[k, 1] + x[i, 2] * w[k, 2]
            pd = x[i, 0] * d[k, 0] + x[i, 1] * d[k, 1] + x[i, 2] * d[k, 2]
            reach = r[i] + slack
            c0 = max(int((pu[i] - reach + 1.0) * half), 0)
            c1 = min(int((pu[i] + reach + 1.0) * half), res - 1)
            r0 = max(int((pw[i] - reach + 1.0) * half), 0)
            r1 = min(int((pw[i] + reach + 1.0) * half), res - 1)
            for row in range(r0, r1 + 1):
                yw = (row + 0.5) / half - 1.0 - pw[i]
                for col in range(c0, c1 + 1):
                    xu = (col + 0.5) / half - 1.0 - pu[i]
                    rho2 = xu * xu + yw * yw
                    if rho2 > reach * reach:
                        continue
                    sil[k, row, col] = True
                    if depth:
                        h = np.sqrt(max(r[i] * r[i] - rho2, 0.0))
                        front[k, row, col] = max(front[k, row, col], pd + h)
                        back[k, row, col] = max(back[k, row, col], -pd + h)
        for e in range(edges.shape[0]):
            # the convex hull of the two discs: pixels p with |p - a_t| <= r_t + slack for
            # some t in [0, 1] (a_t, r_t interpolate the two discs); the excess
            # |p - a_t| - r_t is convex in t, its minimum in closed form
            i, j = edges[e, 0], edges[e, 1]
            au, aw, bu, bw = pu[i], pw[i], pu[j], pw[j]
            ra, rb = r[i] + slack, r[j] + slack
            eu, ew = bu - au, bw - aw
            length = np.sqrt(eu * eu + ew * ew)
            dr = rb - ra
            if length <= abs(dr) + 1e-12:
                continue  # one disc holds the other: nothing beyond the discs
            eu, ew = eu / length, ew / length
            k_ = dr / length
            tan = k_ / np.sqrt(1.0 - k_ * k_)
            c0 = max(int((min(au - ra, bu - rb) + 1.0) * half), 0)
            c1 = min(int((max(au + ra, bu + rb) + 1.0) * half), res - 1)
            r0 = max(int((min(aw - ra, bw - rb) + 1.0) * half), 0)
            r1 = min(int((max(aw + ra, bw + rb) + 1.0) * half), res - 1)
            for row in range(r0, r1 + 1):
                yw = (row + 0.5) / half - 1.0 - aw
                for col in range(c0, c1 + 1):
                    if sil[k, row, col]:
                        continue
                    xu = (col + 0.5) / half - 1.0 - au
                    s = xu * eu + yw * ew
                    hh = abs(xu * ew - yw * eu)
                    t = min(max((s + tan * hh) / length, 0.0), 1.0)
                    du, dw = xu - t * length * eu, yw - t * length * ew
                    rt = ra + t * dr
                    if du * du + dw * dw <= rt * rt:
                        sil[k, row, col] = True
    return sil, front, back


def _unit_balls(
    centers: ArrayLike, radii: ArrayLike, frame: tuple[ArrayLike, float] | None = None
) -> tuple[FloatArray, FloatArray]:
    """Balls about their volume centroid, scaled so the farthest far side is at radius 1;
    or about ``frame``'s centre, divided by its extent."""
    if frame is not None:
        c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
        rr = np.asarray(radii, dtype=np.float64).reshape(-1)
        o, ext = np.asarray(frame[0], dtype=np.float64).reshape(3), float(frame[1])
        if len(c) != len(rr) or not ext > 0 or not np.any(rr > 0):
            raise ValueError(f"{len(c)} centres, {len(rr)} radii, extent {ext}: no light field")
        keep = rr > 0
        return (c[keep] - o) / ext, rr[keep] / ext
    x, r, scale = centred_balls(centers, radii)
    if not scale > 0:
        raise ValueError("no ball of positive radius: no light field")
    extent = float(np.max(np.linalg.norm(x, axis=1) + r))
    return x / extent, r / extent


def _kept_edges(radii: ArrayLike, edges: ArrayLike | None) -> NDArray[np.int64]:
    """(k, 2) contact edges among the balls of positive radius, indexed in that subset."""
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    if edges is None:
        return np.zeros((0, 2), dtype=np.int64)
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if len(e) and (e.min() < 0 or e.max() >= len(r)):
        raise ValueError(f"contact edges index balls outside 0..{len(r) - 1}")
    keep = r > 0
    new = np.cumsum(keep) - 1
    e = e[keep[e[:, 0]] & keep[e[:, 1]]]
    return np.ascontiguousarray(new[e], dtype=np.int64)


def _closed(sil: NDArray[np.bool_], px: int) -> NDArray[np.bool_]:
    """Morphological closing of each image by a disc of ``px`` pixels (image edge padded)."""
    from scipy import ndimage

    yy, xx = np.mgrid[-px : px + 1, -px : px + 1]
    disc = (xx * xx + yy * yy <= px * px + px)[None]
    pad = np.pad(sil, ((0, 0), (px, px), (px, px)))
    out = ndimage.binary_erosion(ndimage.binary_dilation(pad, disc), disc)
    return np.asarray(out[:, px:-px, px:-px] | sil)


def render_discs(
    centers: ArrayLike,
    radii: ArrayLike,
    directions: ArrayLike,
    resolution: int,
    *,
    depth: bool = False,
    edges: ArrayLike | None = None,
    dilate_px: float = 0.0,
    close_px: int = 0,
    frame: tuple[ArrayLike, float] | None = None,
) -> tuple[NDArray[np.bool_], NDArray[np.float32] | None]:
    """Orthographic images of the union of balls, in the unit-sphere frame of the module.

    Parameters
    ----------
    centers : (n, 3) float
        Ball centres, any units.
    radii : (n,) float
        Ball radii, same units (balls of radius <= 0 are left out).
    directions : (m, 3) float
        Unit view directions.
    resolution : int
        Image side, pixels; the image spans [-1, 1]^2 along :func:`image_axes`.
    depth : bool
        Also return the depth images.
    edges : (e, 2) int, optional
        Contact edges (indices into ``centers``): each also fills the convex hull of its
        two balls' discs (the projection of the two balls' convex hull), which closes
        the gap between touching balls. Silhouettes only: depth images show the discs.
    dilate_px : float
        Every disc (and hull) grows by this many pixels, >= 0.
    close_px : int
        Morphological closing of each silhouette by a disc of this many pixels, >= 0.
    frame : ((3,) float, float), optional
        The centre and the extent the balls are seen in (the image spans the disc of
        radius ``extent`` about ``centre``, units of ``centers``); by default the
        balls' volume centroid and the farthest ball's far side.

    Returns
    -------
    silhouettes : (m, resolution, resolution) bool
    depth : (m, 2, resolution, resolution) float32 or None
        Front (seen from ``+d``) and back (from ``-d``, in the same image axes) depth,
        ``(h + 1) / 2`` in [0, 1] where covered, 0 elsewhere; None unless ``depth``.

    Raises
    ------
    ValueError
        If no ball has a positive radius, the arrays' shapes disagree, an edge names
        a ball that does not exist, or ``dilate_px`` / ``close_px`` is negative.
    """
    if not dilate_px >= 0 or close_px < 0:
        raise ValueError(f"dilate_px {dilate_px} and close_px {close_px} must be >= 0")
    x, r = _unit_balls(centers, radii, frame)
    e = _kept_edges(radii, edges)
    d = np.asarray(directions, dtype=np.float32).reshape(-1, 3)
    u, w = image_axes(d)
    res = int(resolution)
    sil, front, back = _splat_discs(
        x.astype(np.float32), r.astype(np.float32), e, u, w, d, res, bool(depth),
        float(dilate_px) * 2.0 / res,
    )  # fmt: skip
    if close_px > 0:
        sil = _closed(sil, int(close_px))
    if not depth:
        return sil, None
    img = np.stack([front, back], axis=1)
    return sil, np.where(img > -2.0, np.clip((img + 1.0) / 2.0, 0.0, 1.0), 0.0).astype(np.float32)


def ball_light_field(
    centers: ArrayLike,
    radii: ArrayLike,
    config: LightFieldConfig | None = None,
    *,
    edges: ArrayLike | None = None,
    frame: tuple[ArrayLike, float] | None = None,
) -> FloatArray:
    """The light fields of a ball union: (n_fields, 10, :func:`light_field_dim`) float64.

    Parameters
    ----------
    centers : (n, 3) float
        Ball centres (a decomposition's), any units.
    radii : (n,) float
        Ball radii, same units.
    config : LightFieldConfig, optional
        Fields, resolution, orders, weights, and how silhouettes are filled
        (``edges``, ``dilate_px``, ``close_px``: :func:`render_discs`).
    edges : (e, 2) int, optional
        The decomposition's contact edges; needed when ``config.edges``, ignored
        otherwise.
    frame : ((3,) float, float), optional
        Centre and extent the balls are seen in (:func:`render_discs`).

    Returns
    -------
    (config.n_fields, 10, dim) float64
        Per light field and dodecahedron view, :func:`silhouette_features` of the disc
        union's silhouette, then (``depth_weight > 0``) ``depth_weight`` times the
        sum and the absolute difference of the front and back depth images' Zernike
        magnitudes. Invariant to translation and scale of the balls; rotations are
        handled by :func:`light_field_distance`.

    Raises
    ------
    ValueError
        If no ball has a positive radius, or ``config.edges`` is set without ``edges``.
    """
    cfg = config or LightFieldConfig()
    if cfg.edges and edges is None:
        raise ValueError("light fields with lf_edges need the decomposition's contact edges")
    depth = cfg.depth_weight > 0
    dirs = field_directions(cfg.n_fields, cfg.seed)
    sil, dep = render_discs(
        centers, radii, dirs, cfg.resolution, depth=depth,
        edges=edges if cfg.edges else None, dilate_px=cfg.dilate_px, close_px=cfg.close_px,
        frame=frame,
    )  # fmt: skip
    feats = silhouette_features(sil, cfg)
    if dep is not None:
        m, res = len(dirs), cfg.resolution
        z = zernike_magnitudes(dep.reshape(2 * m, res, res), cfg.zernike_order).reshape(m, 2, -1)
        both = np.hstack([z[:, 0] + z[:, 1], np.abs(z[:, 0] - z[:, 1])])
        feats = np.hstack([feats, cfg.depth_weight * both])
    return feats.reshape(cfg.n_fields, 10, -1)


def record_light_field(
    centers: ArrayLike,
    radii: ArrayLike,
    config: LightFieldConfig | None = None,
    *,
    edges: ArrayLike | None = None,
    frame: tuple[ArrayLike, float] | None = None,
) -> NDArray[np.float32]:
    """:func:`ball_light_field` as a store keeps it: float32, computed with one BLAS thread.

    The Zernike projections are small matrix products on which a multi-threaded BLAS
    spends more time waking threads than computing, so the call is limited to one BLAS
    thread (:mod:`threadpoolctl`) whatever the process's setting.

    Returns
    -------
    (config.n_fields, 10, dim) float32

    Raises
    ------
    ValueError
        If no ball has a positive radius, or ``config.edges`` is set without ``edges``.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return ball_light_field(centers, radii, config, edges=edges, frame=frame).astype(np.float32)


def inside_light_field(
    inside: Inside, config: LightFieldConfig | None = None
) -> NDArray[np.float32]:
    """Light fields of the inside cells, each a ball of half a cell, as a store keeps them.

    :func:`shapedb.lightfield.record_light_field` of the shell's cells, normalised as a
    ball union is but over all the inside cells: about their centroid, the farthest
    cell's far side at radius 1 (the farthest inside cell is a shell cell).

    Returns
    -------
    (config.n_fields, 10, dim) float32
        As :func:`shapedb.lightfield.ball_light_field` (``config.edges`` has no effect:
        cells have no contact edges).

    Raises
    ------
    ValueError
        If no cell is inside.
    """
    if inside.count == 0 or not len(inside.shell):
        raise ValueError("the field has no inside cell: no light field")
    cfg = config or LightFieldConfig()
    half = 0.5 * inside.cell
    extent = float(np.max(np.linalg.norm(inside.shell - inside.centroid, axis=1))) + half
    radii = np.full(len(inside.shell), half)
    cfg = replace(cfg, edges=False) if cfg.edges else cfg
    return record_light_field(inside.shell, radii, cfg, frame=(inside.centroid, extent))


def decomposition_light_field(
    decomposition: Decomposition, config: LightFieldConfig | None = None
) -> NDArray[np.float32]:
    """:func:`record_light_field` of a decomposition's balls and its tail, if any; with
    ``config.source == "field"``, :func:`inside_light_field` of its inside.

    The balls are :meth:`shapedb.mdbd.Decomposition.longer_packing` (the decomposition's
    balls, then the tail that ``decompose(tail_balls=...)`` packed past them; with
    ``LightFieldConfig.n_balls`` the ingest and an outside query decompose with the same
    tail). With ``config.edges`` and a tail, the contact edges are those of all the
    balls at the decomposition's contact tolerance; without a tail, its own edges.

    Returns
    -------
    (config.n_fields, 10, dim) float32

    Raises
    ------
    ValueError
        If no ball has a positive radius.
    ConfigError
        With ``source="field"``, if the decomposition has no inside (it was not
        decomposed with ``keep_inside=True``).
    """
    cfg = config or LightFieldConfig()
    if cfg.source == "field":
        if decomposition.inside is None:
            from shapedb.errors import ConfigError

            raise ConfigError(
                "light fields of the field need the decomposition's inside: decompose "
                "with keep_inside=True (as ingest does for lf_source=field)"
            )
        return inside_light_field(decomposition.inside, cfg)
    centers, radii = decomposition.longer_packing()
    edges = decomposition.edges
    if cfg.edges and len(radii) > decomposition.n_balls:
        from shapedb.graph import contact_edges

        tol = decomposition.config.contact_tol_cells * decomposition.spacing
        edges = contact_edges(centers, radii, tol)
    return record_light_field(centers, radii, cfg, edges=edges)


# --------------------------------------------------------------------------------------
# The distance
# --------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def _permutation_matrix() -> FloatArray:
    """(100, 60): column r sums the view distances D[v, perm[r, v]] of a flattened (10, 10) D."""
    perm = view_permutations()
    out = np.zeros((100, 60))
    for r in range(60):
        out[np.arange(10) * 10 + perm[r], r] = 1.0
    return out


def light_field_distance(
    descriptors: ArrayLike, others: ArrayLike | None = None, *, chunk: int = 64
) -> FloatArray:
    """Light field distances between shapes: (n, m) float64.

    Parameters
    ----------
    descriptors : (n, fields, 10, d) float
        Query shapes' light fields (e.g. :func:`ball_light_field`).
    others : (m, fields', 10, d) float, optional
        Candidate shapes' light fields; defaults to ``descriptors``.
    chunk : int
        Candidates compared at once (bounds memory: about ``chunk * fields * fields' *
        800`` bytes).

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
    from scipy.spatial.distance import cdist

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
    perm = _permutation_matrix()
    bf = b.reshape(m * fb * 10, d)
    symmetric = others is None
    out = np.zeros((n, m))
    for i in range(n):
        for s in range(i if symmetric else 0, m, chunk):
            e = min(s + chunk, m)
            dist = cdist(a[i].reshape(fa * 10, d), bf[s * fb * 10 : e * fb * 10], "cityblock")
            dist = dist.reshape(fa, 10, e - s, fb, 10).transpose(2, 0, 3, 1, 4)
            sums = dist.reshape(e - s, fa * fb, 100) @ perm
            out[i, s:e] = sums.reshape(e - s, -1).min(axis=1)
    if symmetric:
        out = np.triu(out) + np.triu(out, 1).T
    return out
