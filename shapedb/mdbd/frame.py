"""Canonical grid frame of a solid: centroid and principal axes (private).

The decomposition's fine grid is laid in this frame (:func:`frame_grid`), anchored
at the centroid, so a rigid motion of the model moves the grid with it. The greedy
packing is chaotic: a frame that is off by a fraction of a degree already changes
the decomposition after a handful of balls, so the frame has to follow a rotation to
rounding, not to sampling accuracy.

* **Meshes and point clouds**: moments of the representation's own data, which
  move exactly with the model: the triangles' area moments (a quadrature exact
  for cubic polynomials on each triangle) or the points' moments. The extent along
  the axes is that of the vertices (points). Cost: one pass over the faces.
* **Moved copies** (:class:`shapedb.geometry.base.Transformed`, the implicit
  ``Transformed`` of ``rotate``/``translate``/``scale``): the child's frame, moved
  by the copy's own (proper) similarity transform, so it is exactly covariant too.
* **Everything else** (implicit solids, voxels): two coarse
  passes (a ``frame_resolution`` grid) give the solid's volume moments from
  smooth occupancy weights ``clip(D/h + 1/2, 0, 1)``; the second pass lies along
  the first estimate. This follows a rotation only to a fraction of a degree
  (``docs/results.md``, "Ingest").

From the moments: centroid, principal axes (largest variance first), axis signs
from the third moments, right-handed. Where the frame is not determined by the
moments (isotropic inertia: spheres, cubes, regular solids; equal pairs of
moments: solids of revolution; symmetric axes without a third moment), the
undetermined axes fall back to the model's axes.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from shapedb.config.core import MDBDConfig
from shapedb.errors import DegenerateGeometryError
from shapedb.geometry.base import Geometry, Grid

__all__ = ["canonical_frame", "frame_grid"]

_DEGENERATE = 1e-2  # relative gap of principal moments below which their axes are a tie
_SKEW = 0.02  # |normalised third moment| below which an axis has no preferred sign
# The same for exact moments (meshes, point clouds): only rounding can tie them, and
# eigenvectors of a gap g move by ~1e-16 / g under rounding.
_DEGENERATE_EXACT = 1e-7
_SKEW_EXACT = 1e-7


def _tie_axes(V: NDArray[np.float64], pair: tuple[int, int]) -> NDArray[np.float64]:
    """Replace the tied axes ``pair`` by model axes projected onto their plane."""
    other = ({0, 1, 2} - set(pair)).pop()
    a = V[:, other]
    e = np.eye(3)[int(np.argmin(np.abs(a)))]
    u = e - (e @ a) * a
    u /= np.linalg.norm(u)
    out = V.copy()
    out[:, pair[0]], out[:, pair[1]] = u, np.cross(a, u)
    return out


def _axes(
    P: NDArray[np.float64],
    w: NDArray[np.float64],
    degenerate: float = _DEGENERATE,
    skew_tol: float = _SKEW,
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """Principal axes (3, 3), as columns, and centroid (3,) of weighted samples.

    ``P`` (n, 3) model units, ``w`` (n,) weights (quadrature weights may be
    negative; their sum must be > 0). Principal moments closer than ``degenerate``
    (relative to the largest) are a tie; an axis whose normalised third moment is
    below ``skew_tol`` has no preferred sign. None when the total weight is not
    positive.
    """
    mass = float(w.sum())
    if not mass > 0:
        return None
    c = w @ P / mass
    X = P - c
    C = (X * w[:, None]).T @ X / mass
    lam, V = np.linalg.eigh(C)
    lam, V = lam[::-1].clip(min=0.0), V[:, ::-1]
    tol = degenerate * lam[0]
    if lam[0] - lam[2] <= tol:  # isotropic: no preferred axes at all
        V = np.eye(3)
    elif lam[0] - lam[1] <= tol:
        V = _tie_axes(V, (0, 1))
    elif lam[1] - lam[2] <= tol:
        V = _tie_axes(V, (1, 2))
    Y = X @ V
    skew = (w @ Y**3) / mass / np.maximum(lam, 1e-12 * lam[0] + 1e-300) ** 1.5
    for k in range(3):
        s = skew[k] if abs(skew[k]) > skew_tol else V[int(np.argmax(np.abs(V[:, k]))), k]
        if s < 0:
            V[:, k] = -V[:, k]
            skew[k] = -skew[k]
    if np.linalg.det(V) < 0:  # right-handed: flip the axis whose sign is least certain
        V[:, int(np.argmin(np.abs(skew)))] *= -1.0
    return V, c


def _moments(
    geometry: Geometry, bounds: NDArray[np.float64], cfg: MDBDConfig
) -> (
    tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]
    | None
):
    """One coarse pass over ``bounds``: (axes, centroid, lo, hi, coarse cell) or None.

    ``axes`` has the principal axes as columns (largest moment first); ``lo``/``hi``
    bound the solid along them, relative to the centroid.
    """
    grid = Grid.fit(bounds, resolution=cfg.frame_resolution, padding=2)
    F = np.asarray(geometry.grid_sdf(grid), dtype=np.float64).ravel()
    hc = grid.spacing
    P = grid.points()
    found = _axes(P, np.clip(F / hc + 0.5, 0.0, 1.0))
    if found is None:
        return None
    V, c = found
    # Support of the solid along each axis: every cell bounds it by its projection
    # plus (upper side) or minus (lower side) its distance; cells near or inside only.
    near = F > -hc
    Yn, Fn = (P[near] - c) @ V, F[near][:, None]
    lo, hi = (Yn - Fn).min(axis=0), (Yn + Fn).max(axis=0)
    return V, c, lo, hi, hc


# Quadrature on a triangle exact for cubic polynomials (Strang-Fix, 4 points):
# barycentric coordinates (4, 3) and weights (4,) per unit area.
_TRI_BARY = np.array([[1 / 3, 1 / 3, 1 / 3], [0.6, 0.2, 0.2], [0.2, 0.6, 0.2], [0.2, 0.2, 0.6]])
_TRI_WEIGHT = np.array([-27.0, 25.0, 25.0, 25.0]) / 48.0


def _samples(
    geometry: Geometry,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None:
    """Weighted samples of a mesh's surface or a cloud's points, and its support points.

    Returns (P (n, 3), w (n,), support (k, 3)), model units, or None for other
    representations. Both follow a rigid motion of the data exactly (to rounding).
    """
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.geometry.pointcloud import PointCloud

    if isinstance(geometry, TriangleMesh):
        v, f = np.asarray(geometry.vertices, dtype=np.float64), np.asarray(geometry.faces)
        tri = v[f]  # (m, 3, 3)
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        P = np.einsum("qk,mkd->mqd", _TRI_BARY, tri).reshape(-1, 3)
        w = (area[:, None] * _TRI_WEIGHT[None, :]).ravel()
        return P, w, v[np.unique(f)]
    if isinstance(geometry, PointCloud):
        p = np.asarray(geometry.points, dtype=np.float64)
        return p, np.ones(len(p)), p
    return None


def _data_frame(
    geometry: Geometry, cfg: MDBDConfig
) -> (
    tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]
    | None
):
    """The frame from the representation's own data (meshes, point clouds), or None."""
    data = _samples(geometry)
    if data is None:
        return None
    P, w, support = data
    found = _axes(P, w, _DEGENERATE_EXACT, _SKEW_EXACT)
    if found is None or len(support) == 0:
        return None
    V, c = found
    Y = (support - c) @ V
    lo, hi = Y.min(axis=0), Y.max(axis=0)
    extent = float((hi - lo).max())
    if not extent > 0:
        return None
    return V, c, lo, hi, extent / max(cfg.frame_resolution - 4, 1)


def _moved_frame(
    geometry: Geometry, cfg: MDBDConfig
) -> (
    tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]
    | None
):
    """A moved copy's frame: its child's frame moved along, or None if not a moved copy.

    ``x -> s R x + t`` with ``det R = +1`` (a reflection changes handedness: the
    frame is computed afresh).
    """
    from shapedb.geometry import base as geo
    from shapedb.geometry import implicit as imp

    child: Geometry
    if isinstance(geometry, imp.Transformed):
        child, R, t, s = geometry.child, geometry.rotation, geometry.translation, geometry.factor
    elif isinstance(geometry, geo.Transformed):
        child, R, t, s = geometry.child, geometry.rotation, geometry.translation, 1.0
    else:
        return None
    if not np.linalg.det(R) > 0:
        return None
    found = canonical_frame(child, cfg)
    if found is None:
        return None
    V, c, lo, hi, hc = found
    return R @ V, s * (R @ c) + t, s * lo, s * hi, s * hc


def canonical_frame(
    geometry: Geometry, cfg: MDBDConfig
) -> (
    tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]
    | None
):
    """(rotation, centroid, local lo, local hi, coarse cell), or None if nothing is inside.

    Moved copies: the child's frame, moved (:func:`_moved_frame`); meshes and point
    clouds: from their own data (:func:`_data_frame`); both exactly covariant.
    Otherwise two coarse passes: the first on the model's axes, the second on a grid laid along
    the first estimate. The sampling error of the moments depends on how the grid
    lies on the solid; in the second pass it lies (almost) the same way whatever the
    model's orientation, so the frame's dependence on the orientation drops from
    ~0.1-0.5 degree and ~0.05 cell to second order.
    """
    exact = _moved_frame(geometry, cfg)
    if exact is None:
        exact = _data_frame(geometry, cfg)
    if exact is not None:
        return exact
    first = _moments(geometry, geometry.bounds, cfg)
    if first is None:
        return None
    V1, c1, lo1, hi1, hc = first
    local = geometry.transformed(V1.T, -V1.T @ c1)
    second = _moments(local, np.stack([lo1 - hc, hi1 + hc]), cfg)
    if second is None:
        return first
    V2, c2, lo, hi, hc = second
    return V1 @ V2, c1 + V1 @ c2, lo, hi, hc


def frame_grid(
    lo: NDArray[np.float64], hi: NDArray[np.float64], margin: float, cfg: MDBDConfig
) -> Grid:
    """Grid of the local frame: ``resolution`` cells along the longest extent, a lattice
    through the origin (the centroid), covering ``lo - margin .. hi + margin`` plus padding."""
    extent = float((hi - lo).max())
    if not extent > 0:
        raise DegenerateGeometryError(f"solid has zero extent along its principal axes: {extent}")
    h = extent / max(cfg.resolution - 2 * cfg.padding_cells, 1)
    i0 = np.floor((lo - margin) / h).astype(np.int64) - cfg.padding_cells
    i1 = np.ceil((hi + margin) / h).astype(np.int64) + cfg.padding_cells
    shape = i1 - i0 + 1
    return Grid(
        origin=h * i0.astype(np.float64),
        spacing=float(h),
        shape=(int(shape[0]), int(shape[1]), int(shape[2])),
    )
