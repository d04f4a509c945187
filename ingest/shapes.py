"""Geometry objects from arrays a file held, refused when their coordinates are absurd.

Every loader of :mod:`ingest.loaders` builds its shape here, so that each format gets
the same checks: NaN or infinite values (:class:`~shapedb.errors.NonFiniteGeometryError`),
magnitudes beyond :data:`MAX_COORDINATE`, and point clouds whose farthest points lie
:data:`OUTLIER_RATIO` times beyond the rest (:class:`~shapedb.errors.InvalidShapeError`).
Messages give the reason; the loader adds the file's name.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from shapedb.errors import InvalidShapeError, NonFiniteGeometryError
from shapedb.geometry.base import Geometry

__all__ = [
    "MAX_COORDINATE",
    "OUTLIER_RATIO",
    "check_coordinates",
    "check_outliers",
    "mesh_geometry",
    "cloud_geometry",
    "voxel_geometry",
]

#: Largest coordinate magnitude read: 1e12 is a million km in mm, beyond any model;
#: a corrupt value (1e30, 1e308) would otherwise squash the shape into one cell.
MAX_COORDINATE = 1e12
#: A cloud point this many times farther from the centre than 90% of the cloud is an
#: outlier: the bulk would then span under one cell of a 256-cell grid (no model).
OUTLIER_RATIO = 1e3


def check_coordinates(values: Any, what: str) -> NDArray[np.float64]:
    """``values`` as float64, refused when NaN, infinite or beyond :data:`MAX_COORDINATE`."""
    try:
        a = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidShapeError(f"{what} are not real numbers: {exc}") from None
    finite = np.isfinite(a)
    if not finite.all():
        rows = int((~finite).reshape(len(a), -1).any(axis=1).sum()) if a.ndim else 1
        raise NonFiniteGeometryError(
            f"{rows} of {max(len(a), 1) if a.ndim else 1} {what} have NaN or infinite values"
        )
    top = float(np.abs(a).max()) if a.size else 0.0
    if top > MAX_COORDINATE:
        raise InvalidShapeError(
            f"{what} reach {top:.3g}, beyond the limit {MAX_COORDINATE:.0e} "
            "(a corrupt value, or units no model uses)"
        )
    return a


def check_outliers(points: NDArray[np.float64]) -> None:
    """Refuse a cloud whose farthest points dwarf the rest (see :data:`OUTLIER_RATIO`)."""
    if len(points) < 10:
        return
    d = np.linalg.norm(points - np.median(points, axis=0), axis=1)
    bulk = float(np.quantile(d, 0.9))
    far = np.flatnonzero(d > OUTLIER_RATIO * bulk)
    if bulk > 0 and len(far):
        i = int(far[np.argmax(d[far])])
        raise InvalidShapeError(
            f"{len(far)} of {len(points)} points lie over {OUTLIER_RATIO:g}x farther from "
            f"the cloud's centre than 90% of the others (outliers: e.g. point {i} at "
            f"{np.array2string(points[i], precision=3)})"
        )


def mesh_geometry(vertices: Any, faces: Any, src: str) -> Geometry:
    from shapedb.geometry.mesh import TriangleMesh

    return TriangleMesh(check_coordinates(vertices, "vertices"), faces, name=src)


def cloud_geometry(points: Any, normals: Any, src: str) -> Geometry:
    from shapedb.geometry.pointcloud import PointCloud

    pts = check_coordinates(points, "points")
    if pts.ndim == 2 and pts.shape[1] == 3:
        check_outliers(pts)
    return _construct(PointCloud, pts, normals=normals, name=src)


def voxel_geometry(
    occupancy: Any, origin: Any, pitch: Any, src: str, surface: str = "cubes"
) -> Geometry:
    from shapedb.geometry.voxels import VoxelGrid

    origin = check_coordinates(origin, "origin coordinates")
    pitch = float(check_coordinates(pitch, "voxel pitch values"))
    return _construct(VoxelGrid, occupancy, origin=origin, pitch=pitch, surface=surface, name=src)


def _construct(cls: type, *args: Any, name: str, **kwargs: Any) -> Geometry:
    """Call a representation's constructor, passing ``name`` when it accepts one."""
    import inspect

    try:
        params = inspect.signature(cls).parameters
    except (TypeError, ValueError):  # pragma: no cover
        params = {}  # type: ignore[assignment]
    if "name" in params:
        kwargs["name"] = name
    return cls(*args, **kwargs)  # type: ignore[no-any-return]
