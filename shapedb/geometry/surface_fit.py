"""Local sphere fits to oriented surface samples: a sparse cloud's distance between samples.

Between the samples of a sparse cloud the surface is only estimated. A splat (a disc
in the sample's tangent plane, :mod:`shapedb.geometry.pointcloud`) is flat, so on a curved
surface sampled every few grid cells it is off by the sag of the surface over half
a sample gap. An *algebraic sphere* fitted to the positions and normals of the
samples around a point (APSS: Guennebaud and Gross, "Algebraic point set surfaces",
SIGGRAPH 2007) follows the curvature: ``u0 + u . x + u4 |x|^2 = 0`` minimising, with
Gaussian weights, the squared values at the samples plus the squared misfit of its
gradient to their normals, in closed form. A plane is the case ``u4 = 0``.

:func:`sphere_distance` fits the sphere around a first estimate of each point's
closest surface point, projects the point on it, fits again around the projection,
and returns the distance to the second sphere. How close this comes to the exact
distance, against the splats, is measured in ``docs/results.md`` ("Point-cloud
distance").
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["FIT_NEIGHBOURS", "FIT_WIDTH", "sphere_distance", "fit_spheres"]

FloatArray = NDArray[np.float64]

#: Samples around a surface point that a fit uses.
FIT_NEIGHBOURS = 8
#: Width of the Gaussian weights, in units of the nearest sample's spacing (its
#: distance to its k-th neighbour, :attr:`shapedb.geometry.pointcloud.PointCloud.spacing`).
FIT_WIDTH = 0.5
#: Fits per point: around the first estimate, then around the projection on the fit.
ITERATIONS = 2
#: A fit counts only where the point's projection on it stays this close to where it
#: was fitted, in units of the nearest sample's spacing: beyond, the sphere is an
#: extrapolation of a few samples (at a medial point, where MDBD puts its ball
#: centres, the nearest point of a slightly too curved sphere can lie anywhere).
FIT_REACH = 1.0


def fit_spheres(
    q: FloatArray,
    points: FloatArray,
    normals: FloatArray,
    spacing: FloatArray,
    tree: Any,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Algebraic spheres fitted around surface points ``q``.

    Parameters
    ----------
    q : (n, 3) float
        Where to fit (points on or near the surface), model units.
    points, normals : (m, 3) float
        The samples and their unit outward normals.
    spacing : (m,) float
        Each sample's spacing (distance to its k-th neighbour), model units.
    tree : scipy.spatial.cKDTree
        Over ``points``.

    Returns
    -------
    u0 : (n,) float
    u : (n, 3) float
    u4 : (n,) float
        Coefficients of ``u0 + u . x + u4 |x|^2`` with ``x`` relative to ``q``;
        ``u4`` is 0 where the samples fit no sphere (a plane).
    """
    k = int(min(FIT_NEIGHBOURS, len(points)))
    dist, idx = tree.query(q, k=k)
    dist = np.asarray(dist, dtype=np.float64).reshape(len(q), k)
    idx = np.asarray(idx).reshape(len(q), k)
    h = FIT_WIDTH * spacing[idx[:, 0]][:, None]
    w = np.exp(-((dist / h) ** 2))
    w = w / np.maximum(w.sum(axis=1, keepdims=True), 1e-300)
    s = points[idx] - q[:, None, :]
    n = normals[idx]
    sp = np.einsum("nk,nkj->nj", w, s)
    sn = np.einsum("nk,nkj->nj", w, n)
    spn = np.einsum("nk,nkj,nkj->n", w, s, n)
    spp = np.einsum("nk,nkj,nkj->n", w, s, s)
    den = spp - np.einsum("nj,nj->n", sp, sp)
    ok = den > 1e-12 * np.maximum(spp, 1e-300)
    u4 = np.where(ok, 0.5 * (spn - np.einsum("nj,nj->n", sp, sn)) / np.where(ok, den, 1.0), 0.0)
    u = sn - 2.0 * u4[:, None] * sp
    u0 = -np.einsum("nj,nj->n", u, sp) - u4 * spp
    return u0, u, u4


def _project(
    x: FloatArray, u0: FloatArray, u: FloatArray, u4: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Closest points (n, 3) of x (n, 3) on the spheres (or planes), and distances (n,).

    NaN where the fit has no zero set (no real radius, or a zero gradient).
    """
    g = np.linalg.norm(u, axis=1)
    scale = np.sqrt(np.maximum(np.einsum("nj,nj->n", x, x), 1e-300))
    flat = np.abs(u4) * scale < 1e-6 * g
    with np.errstate(divide="ignore", invalid="ignore"):
        along = (u0 + np.einsum("nj,nj->n", u, x)) / g
        plane = x - along[:, None] * u / g[:, None]
        c = -u / (2.0 * u4[:, None])
        r2 = np.einsum("nj,nj->n", c, c) - u0 / u4
        r = np.sqrt(np.where(r2 > 0, r2, np.nan))
        v = x - c
        vl = np.linalg.norm(v, axis=1)
        sphere = c + v * (r / vl)[:, None]
        d = np.where(flat, np.abs(along), np.abs(vl - r))
    out = np.where(flat[:, None], plane, sphere)
    good = np.isfinite(d) & np.isfinite(out).all(axis=1)
    return out, np.where(good, d, np.nan)


def sphere_distance(
    p: FloatArray,
    q: FloatArray,
    points: FloatArray,
    normals: FloatArray,
    spacing: FloatArray,
    tree: Any,
) -> FloatArray:
    """Distances (n,) of points ``p`` (n, 3) to the spheres fitted near them.

    A fit whose projection of the point lies farther than :data:`FIT_REACH`
    spacings from where it was fitted does not count.

    Parameters
    ----------
    p : (n, 3) float
        Query points, model units.
    q : (n, 3) float
        A first estimate of each point's closest surface point (e.g. on its splat).
    points, normals, spacing, tree
        The samples, as in :func:`fit_spheres`.

    Returns
    -------
    (n,) float64
        Model units; ``inf`` where no fit counts (callers take the nearer of this
        and their own estimate).
    """
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    d = np.full(len(p), np.inf)
    if len(p) == 0:
        return d
    for _ in range(ITERATIONS):
        u0, u, u4 = fit_spheres(q, points, normals, spacing, tree)
        proj, found = _project(p - q, u0, u, u4)
        reach = FIT_REACH * spacing[tree.query(q)[1]]
        ok = np.isfinite(found) & (np.linalg.norm(proj, axis=1) <= reach)
        d = np.where(ok, found, d)
        q = np.where(ok[:, None], proj + q, q)
    return d
