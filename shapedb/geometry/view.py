"""Sparse views: what a shape with an exact surface looks like as a sparse point cloud.

A sparse point cloud (the paper queries 20 % of a mesh's vertices, a sample every
3-5 grid cells) does not bound quite the solid its mesh bounds: between samples the
surface is only estimated, and the greedy packing, which is chaotic, turns that
into a systematic difference (fewer exact contacts; ``docs/studies.md``). Two
sparse clouds of one mesh, on the other hand, decompose alike: clouds against clouds
retrieve nearly as well as meshes against meshes, clouds against meshes worse
(``docs/results.md``, "Across representations").

So a store built with ``CloudConfig(view_cells=s)`` keeps, for every shape that is
not itself a sparse cloud, a second feature: that of a cloud drawn uniformly by area
on its surface (a mesh's faces; for other representations the marching-cubes surface
of their grid SDF) with one sample per ``s`` grid cells of spacing
(:func:`view_geometry`).
Whenever one side of a comparison is a sparse cloud (:func:`is_sparse`), the pair is
as far apart as the cloud is from the nearer of the other side's two features, its
exact one and its view's (:mod:`query.search.engine`): a sparse cloud's packing sometimes
resembles the exact packing more, and taking the nearer of the two widens every
validation set's margin over the view alone. Two exact shapes compare exactly as
before. Everything is still computed from MDBD balls and contact graphs.

The sample count is ``area / (AREA_PER_SAMPLE * (s * cell)^2)``: a uniform sample's
:attr:`~shapedb.geometry.pointcloud.PointCloud.surface_sampling` (distance to the k-th
neighbour) is about ``sqrt(area per sample / AREA_PER_SAMPLE)``. Meshes with hidden
or doubled faces (polygon soups) have more area than surface, so the view's spacing
is then measured and the sample thinned to ``s`` cells (``docs/results.md``,
"Sparse views").
"""

from __future__ import annotations

import hashlib

import numpy as np
from numpy.typing import NDArray

from shapedb.errors import ConfigError
from shapedb.geometry.base import Geometry

__all__ = [
    "SPARSE_CELLS",
    "AREA_PER_SAMPLE",
    "MAX_VIEW_SAMPLES",
    "is_sparse",
    "view_geometry",
    "surface_area",
    "boundary_mesh",
    "ONE_SIDED_LAYERS",
    "GRAZING_SHARE",
    "grazing_share",
    "layered_fraction",
    "is_one_sided",
    "viewing_direction",
]

#: A source sampled more coarsely than this (its ``sampling`` in grid cells) is sparse.
#: The paper's 20 % clouds measure 2.8-5.1 cells (q10-q90), dense clouds of 20,000
#: samples 0.5-1.
SPARSE_CELLS = 2.0
#: Surface area per sample over the squared sample spacing of a uniform sample.
AREA_PER_SAMPLE = 0.33
#: Largest view drawn (a view is meant to be sparse; this bounds absurd surfaces).
MAX_VIEW_SAMPLES = 200_000
#: Fewest samples in a view (below this a point cloud is refused).
MIN_VIEW_SAMPLES = 200
#: A view whose measured spacing is below this fraction of ``view_cells`` is thinned.
THIN_BELOW = 0.97
#: A point cloud is one-sided when fewer than this share of its points have another
#: surface layer on their line of sight, along the direction where that share is least
#: (:func:`layered_fraction`). Validation clouds of CAPOD, parts, web and enclosures: of
#: 160 depth scans 13 measure more, of 480 clouds all around their surface 17 less.
ONE_SIDED_LAYERS = 0.15
#: Directions over the half sphere :func:`layered_fraction` tries.
LAYER_DIRECTIONS = 200
#: Image cells across the cloud's extent in :func:`layered_fraction`; two points of a
#: cell more than two cells apart in depth lie on two layers.
LAYER_CELLS = 24
#: Image cells across the extent when :func:`layered_fraction` looks for the viewing
#: direction: finer than the test's cells, where only the camera's own cap of directions
#: stays one layer deep. Validation scans of CAPOD and parts: the camera's axis missed by
#: 11.8 degrees at the median (25.8 at the 90th percentile) against 23.0 (56.7) at 24
#: cells (32, 48, 64, 128, 192 cells: 17.3, 15.6, 12.5, 11.8, 10.2); of 64, 96, 128 and
#: 192 cells, 96 gave the view path the best NN over four families' validation scans.
DIRECTION_CELLS = 96
#: Directions whose share of two-layer points is within this of the least make the cap
#: whose centre :func:`layered_fraction` returns.
LAYER_CAP = 0.02
#: Fewest points of a cloud that can be called one-sided (fewer fill too few cells).
MIN_ONE_SIDED_POINTS = 100
#: A cloud one layer deep is one-sided only when fewer than this share of its points
#: see the viewing direction edge-on (:func:`grazing_share`): a camera sees a surface
#: edge-on hardly at all, while a cloud around a whole thin model (a chair, a wheel, a
#: sink: one layer deep along some direction) samples its sides as much as any. Validation
#: clouds of CAPOD, parts, enclosures and generic that the layer count calls one-sided,
#: class NN through ``db.search``: depth scans 63 of 162 either way, clouds around whole
#: models 58 of 89 -> 75 (shares of 0.005-0.02: scans 61-62, whole clouds 78-80).
GRAZING_SHARE = 0.03
#: |cos| between a point's normal and the viewing direction below which it sees the
#: direction edge-on (within 5.7 degrees of perpendicular).
GRAZING_COS = 0.1
#: Nearest points whose plane gives a point's normal in :func:`grazing_share`.
GRAZING_NEIGHBOURS = 12
#: Most points :func:`grazing_share` reads (a seeded subset of larger clouds).
GRAZING_POINTS = 20_000


def is_sparse(sampling: float, spacing: float) -> bool:
    """Whether a source with sample spacing ``sampling`` is sparse on a grid of ``spacing``.

    Parameters
    ----------
    sampling : float
        The source's surface sample spacing, model units (0 for exact surfaces;
        :attr:`shapedb.mdbd.decomposition.Decomposition.sampling`).
    spacing : float
        The decomposition's grid cell size, model units.
    """
    if not (np.isfinite(sampling) and np.isfinite(spacing)) or spacing <= 0:
        return False
    return bool(sampling >= SPARSE_CELLS * spacing)


def _half_sphere(n: int) -> NDArray[np.float64]:
    """(n, 3) unit directions spread evenly over the half sphere z >= 0 (a Fibonacci lattice)."""
    k = np.arange(n) + 0.5
    z = 1.0 - k / n
    r = np.sqrt(1.0 - z * z)
    phi = k * np.pi * (3.0 - np.sqrt(5.0))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _two_layer_shares(
    p: NDArray[np.float64], dirs: NDArray[np.float64], cells: int, extent: float
) -> NDArray[np.float64]:
    """(directions,) share of the points ``p`` (n, 3, centred) in image cells (``cells``
    across ``2 * extent``) whose points span more than two cells in depth along each of
    ``dirs`` (half-sphere unit vectors)."""
    cell = 2.0 * extent / cells
    u = np.cross(dirs, [1.0, 0.0, 0.0])  # no direction of the half sphere lies along x
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(dirs, u)
    col = np.floor((p @ u.T) / cell).astype(np.int64) + cells
    row = np.floor((p @ w.T) / cell).astype(np.int64) + cells
    depth = p @ dirs.T  # (n, directions)
    key = row * (4 * cells) + col
    shares = np.empty(len(dirs))
    for j in range(len(dirs)):
        order = np.argsort(key[:, j], kind="stable")
        k, z = key[order, j], depth[order, j]
        starts = np.r_[0, np.flatnonzero(np.diff(k)) + 1]
        spread = np.maximum.reduceat(z, starts) - np.minimum.reduceat(z, starts)
        counts = np.diff(np.r_[starts, len(k)])
        shares[j] = float(counts[spread > 2.0 * cell].sum()) / len(p)
    return shares


def layered_fraction(points: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
    """How far a cloud is from one depth camera's view, and the direction it is nearest to.

    Along a direction ``d`` the points are binned into square cells of the image plane
    (:data:`LAYER_CELLS` across the cloud's extent); a cell whose points span more than two
    cells in depth holds two surface layers, or a wall seen at grazing incidence, which a
    depth camera samples sparsely (measured: a gap test instead, which lets walls pass,
    took thin web models' whole clouds for scans). A depth scan is one layer deep along its
    camera's axis; a cloud around a whole surface is at least two along every direction.
    The direction comes from the same count on finer cells (:data:`DIRECTION_CELLS`).

    Parameters
    ----------
    points : (n, 3) float
        n >= 1, finite.

    Returns
    -------
    (float, (3,) float64)
        The least share of points in two-layer cells over :data:`LAYER_DIRECTIONS`
        directions (in [0, 1]), and the centre (unit) of the directions whose share on
        :data:`DIRECTION_CELLS` cells is within :data:`LAYER_CAP` of that count's least.
    """
    p = np.asarray(points, np.float64).reshape(-1, 3)
    p = p - p.mean(axis=0)
    extent = float(np.sqrt((p * p).sum(axis=1)).max())
    dirs = _half_sphere(LAYER_DIRECTIONS)
    if not extent > 0:
        return 0.0, dirs[-1]
    share = float(_two_layer_shares(p, dirs, LAYER_CELLS, extent).min())
    fine = _two_layer_shares(p, dirs, DIRECTION_CELLS, extent)
    best = int(np.argmin(fine))
    # a scan is one layer deep over a cap of directions about its camera's: its centre
    cap = dirs[fine <= fine[best] + LAYER_CAP]
    cap = cap * np.sign(cap @ dirs[best])[:, None]
    mean = cap.sum(axis=0)
    return share, np.asarray(mean / np.linalg.norm(mean))


def viewing_direction(geometry: Geometry) -> NDArray[np.float64] | None:
    """The direction (3,) a one-sided cloud was seen along, up to sign; None when it is
    not one (:func:`is_one_sided`), or is no point cloud.

    The direction along which its points lie in one layer (:func:`layered_fraction`), when
    few of them see it edge-on (:func:`grazing_share`).
    """
    from shapedb.geometry.pointcloud import PointCloud

    if not isinstance(geometry, PointCloud) or len(geometry.points) < MIN_ONE_SIDED_POINTS:
        return None
    share, direction = layered_fraction(geometry.points)
    if share >= ONE_SIDED_LAYERS or grazing_share(geometry.points, direction) >= GRAZING_SHARE:
        return None
    return direction


def grazing_share(points: NDArray[np.float64], direction: NDArray[np.float64]) -> float:
    """The share of a cloud's points whose surface is seen edge-on along ``direction``.

    A point's normal is the least axis of its :data:`GRAZING_NEIGHBOURS` nearest points
    (orientation does not matter); it sees ``direction`` edge-on when ``|cos|`` between the
    two is below :data:`GRAZING_COS`. Clouds of more than :data:`GRAZING_POINTS` points are
    read through a seeded subset of them.

    Parameters
    ----------
    points : (n, 3) float
        n >= 3, finite.
    direction : (3,) float
        Unit viewing direction.

    Returns
    -------
    float
        In [0, 1].

    Raises
    ------
    ValueError
        Fewer than 3 points.
    """
    from scipy.spatial import cKDTree

    p = np.asarray(points, np.float64).reshape(-1, 3)
    if len(p) < 3:
        raise ValueError(f"grazing_share needs 3 or more points ({len(p)} given)")
    if len(p) > GRAZING_POINTS:
        p = p[np.sort(np.random.default_rng(0).choice(len(p), GRAZING_POINTS, replace=False))]
    k = min(GRAZING_NEIGHBOURS, len(p))
    _, near = cKDTree(p).query(p, k=k)
    x = p[near] - p[near].mean(axis=1, keepdims=True)
    _, axes = np.linalg.eigh(np.einsum("nki,nkj->nij", x, x))
    cos = np.abs(axes[:, :, 0] @ np.asarray(direction, np.float64))
    return float(np.mean(cos < GRAZING_COS))


def is_one_sided(geometry: Geometry) -> bool:
    """Whether ``geometry`` is a point cloud that samples only one side of its solid:
    a depth camera's scan, the faces of a model visible from one side. False for a cloud
    around the whole solid, one of fewer than :data:`MIN_ONE_SIDED_POINTS` points, and
    every geometry that is not a point cloud."""
    return viewing_direction(geometry) is not None


def view_geometry(geometry: Geometry, spacing: float, view_cells: float) -> Geometry | None:
    """The sparse view of ``geometry``: a point cloud on its surface, or None.

    Parameters
    ----------
    geometry : Geometry
        A shape known exactly, or densely enough (its ``surface_sampling`` below
        :data:`SPARSE_CELLS` grid cells). A triangle mesh is sampled on its faces;
        any other representation (implicit solids, voxel grids, CAD solids, dense
        clouds) on the marching-cubes surface of its grid SDF at ``spacing``
        (:func:`boundary_mesh`).
    spacing : float
        Grid cell size of ``geometry``'s own decomposition, model units.
    view_cells : float
        Sample spacing of the view, in grid cells (``CloudConfig.view_cells``).

    Returns
    -------
    PointCloud or None
        None when the geometry has no surface to sample. Deterministic: the sample
        is seeded by the geometry's bounds.
    """
    if view_cells <= 0:
        raise ConfigError(f"view_cells={view_cells!r} is invalid: views need a positive spacing")
    if not np.isfinite(spacing) or spacing <= 0:
        return None
    surface: Geometry | None = geometry
    if getattr(geometry, "faces", None) is None or not hasattr(geometry, "sample_surface"):
        surface = boundary_mesh(geometry, spacing)
    if surface is None:
        return None
    area = surface_area(surface.vertices, surface.faces)  # type: ignore[attr-defined]
    if not np.isfinite(area) or area <= 0:
        return None
    from shapedb.geometry.pointcloud import PointCloud

    n = area / (AREA_PER_SAMPLE * (view_cells * spacing) ** 2)
    n = int(np.clip(np.round(n), MIN_VIEW_SAMPLES, MAX_VIEW_SAMPLES))
    rng = np.random.default_rng(_seed(geometry))
    points: NDArray[np.float64] = surface.sample_surface(n, seed=rng)  # type: ignore[attr-defined]
    name = f"{getattr(geometry, 'name', None) or 'shape'} (view)"
    cloud = PointCloud(points, name=name)
    # hidden or doubled faces (polygon soups) make the area, hence the count, too
    # large: thin to the spacing the sample actually measures
    cells = cloud.surface_sampling / spacing
    if cells < THIN_BELOW * view_cells:
        keep = max(MIN_VIEW_SAMPLES, int(round(len(cloud.points) * (cells / view_cells) ** 2)))
        if keep < len(cloud.points):
            cloud = PointCloud(
                cloud.points[rng.choice(len(cloud.points), keep, replace=False)], name=name
            )
    return cloud


def boundary_mesh(geometry: Geometry, spacing: float) -> Geometry | None:
    """The boundary of ``geometry`` as a triangle mesh: marching cubes on its grid SDF.

    The grid has cells of ``spacing`` (model units; at most 512 along the longest
    side). None when the field has no zero crossing (nothing inside, or no outside).
    """
    from skimage import measure

    from shapedb.geometry.base import Grid
    from shapedb.geometry.mesh import TriangleMesh

    b = np.asarray(geometry.bounds, dtype=np.float64)
    longest = float((b[1] - b[0]).max())
    resolution = int(np.clip(np.ceil(longest / spacing) + 4, 8, 512))
    grid = Grid.fit(b, resolution=resolution, padding=2)
    field = np.asarray(geometry.grid_sdf(grid), dtype=np.float32)
    if not (np.nanmax(field) > 0 > np.nanmin(field)):
        return None
    verts, faces, _, _ = measure.marching_cubes(field, level=0.0, spacing=(grid.spacing,) * 3)
    return TriangleMesh(verts + grid.origin, faces, name=getattr(geometry, "name", None))


def surface_area(vertices: NDArray[np.floating], faces: NDArray[np.integer]) -> float:
    """Total area of triangles ``faces`` (m, 3) over ``vertices`` (v, 3), model units squared."""
    tri = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return float(0.5 * np.linalg.norm(cross, axis=1).sum())


def _seed(geometry: Geometry) -> int:
    """A seed from the geometry's bounds, so that a view is reproducible."""
    key = np.asarray(geometry.bounds, np.float64).tobytes()
    return int.from_bytes(hashlib.sha256(key).digest()[:8], "little")
