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
    "ONE_SIDED_RESULTANT",
    "normal_resultant",
    "is_one_sided",
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
#: A point cloud whose area-weighted mean outward normal is at least this long is
#: one-sided: closed clouds (sphere, cube) measure under 0.01, half a sphere 0.50, three
#: faces of a cube 0.40; 97 % of horizontal camera views of generated parts reach it.
ONE_SIDED_RESULTANT = 0.25


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


def normal_resultant(geometry: Geometry) -> float:
    """Length of the area-weighted mean unit normal of a point cloud, in [0, 1].

    A closed surface's outward normals integrate to zero (the divergence theorem), so a
    cloud sampling all of a solid's boundary scores near 0; one seen from a single side
    (a depth camera's view) has its normals in one hemisphere and scores far from it
    (a half sphere 0.5). The sign of the normals does not matter: a consistently
    inward-oriented cloud scores the same. Any other geometry (exact surfaces) scores 0.

    Parameters
    ----------
    geometry : Geometry
        A :class:`~shapedb.geometry.pointcloud.PointCloud` (its given or estimated
        normals and per-point areas); anything else.
    """
    from shapedb.geometry.pointcloud import PointCloud

    if not isinstance(geometry, PointCloud):
        return 0.0
    areas = np.asarray(geometry.areas, np.float64)
    total = float(areas.sum())
    if not np.isfinite(total) or total <= 0:
        return 0.0
    mean = (np.asarray(geometry.normals, np.float64) * areas[:, None]).sum(axis=0) / total
    return float(min(float(np.linalg.norm(mean)), 1.0))


def is_one_sided(geometry: Geometry) -> bool:
    """Whether ``geometry`` is a point cloud that samples only one side of its solid.

    True when :func:`normal_resultant` reaches :data:`ONE_SIDED_RESULTANT`: a scan from
    one viewpoint, the visible faces of a model; False for a cloud around the whole
    solid and for every geometry that is not a point cloud.
    """
    return normal_resultant(geometry) >= ONE_SIDED_RESULTANT


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
