"""Reconstructions: what a sparse point cloud looks like as a closed surface.

A sparse cloud (the paper queries 20 % of a mesh's vertices, a sample every 3-5 grid
cells) packs differently from its mesh (:mod:`shapedb.geometry.view`). Stores with views meet
it half way from the mesh's side; this module meets it from the cloud's side: the
cloud's screened Poisson surface (Kazhdan and Hoppe 2013, open3d), decomposed as a
mesh, gives the cloud a second feature, compared with the *exact* features of dense
shapes. A pair of a sparse cloud and a dense shape is then as far apart as the nearest
of their comparisons (:mod:`query.search.engine`).

Poisson closes every surface, so it swells open sheets and polygon soups and rounds
what the samples leave unresolved. A reconstruction is therefore kept only when its
packing's volume (the balls are disjoint: ``sum r^3``) agrees with the cloud's own
packing's within :data:`VOLUME_TOLERANCE` (:func:`volumes_agree`).

The reconstruction works on a copy of the cloud in its decomposition's frame, so its
normals are estimated as the decomposition's were and the cloud keeps no state from
it. It costs about one more decomposition per sparse cloud; what it changes in
retrieval, and what it costs, is measured in ``docs/results.md`` ("Reconstructions").
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from shapedb.config.core import CloudConfig
from shapedb.errors import ShapeDBError
from shapedb.geometry.base import Geometry

__all__ = ["DEPTH", "VOLUME_TOLERANCE", "reconstruct", "reconstructed", "volumes_agree"]

log = logging.getLogger(__name__)

#: Default octree depth of the Poisson solve (2^7 cells along the box at the finest
#: level; the 20 % clouds have 1,400-5,000 samples); stores record theirs as
#: ``CloudConfig.reconstruct_depth``.
DEPTH: int = CloudConfig.reconstruct_depth
#: Largest ratio between the ball volumes of a cloud's packing and of its
#: reconstruction's for the reconstruction to count (chosen on the validation
#: splits; ``docs/results.md``, "Reconstructions").
VOLUME_TOLERANCE = 1.3


def reconstruct(cloud: Geometry, *, depth: int = DEPTH) -> Geometry | None:
    """The screened Poisson surface of a point cloud, as a triangle mesh (or None).

    Parameters
    ----------
    cloud : PointCloud
        Samples with (given or estimated) oriented normals.
    depth : int
        Octree depth of the solve.

    Returns
    -------
    TriangleMesh or None
        None when ``cloud`` is not a point cloud or the solve gives no surface.
    """
    from shapedb.geometry.mesh import TriangleMesh
    from shapedb.geometry.pointcloud import PointCloud

    if not isinstance(cloud, PointCloud):
        return None
    import open3d as o3d

    o = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.array(cloud.points)))
    o.normals = o3d.utility.Vector3dVector(np.array(cloud.normals))
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        mesh, _ = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
            o, depth=int(depth), n_threads=1
        )
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    if len(f) == 0 or not np.all(np.isfinite(v)):
        return None
    try:
        return TriangleMesh(v, f, name=getattr(cloud, "name", None))
    except ShapeDBError:
        return None


def volumes_agree(radii: np.ndarray, other: np.ndarray) -> bool:
    """Whether two packings' ball volumes (``sum r^3`` of ``radii``, ``other``) agree.

    Within a factor :data:`VOLUME_TOLERANCE` either way.
    """
    a = float(np.sum(np.asarray(radii, np.float64) ** 3))
    b = float(np.sum(np.asarray(other, np.float64) ** 3))
    if not (a > 0 and b > 0):
        return False
    return 1.0 / VOLUME_TOLERANCE < b / a < VOLUME_TOLERANCE


def reconstructed(
    geometry: Geometry, decomposition: Any, config: Any, *, depth: int = DEPTH
) -> Any:
    """The kept decomposition of ``geometry``'s reconstruction, or None.

    Parameters
    ----------
    geometry : Geometry
        A sparse point cloud (anything else gives None).
    decomposition : Decomposition
        ``geometry``'s own decomposition (its ball volume is the reference).
    config : MDBDConfig
        The decomposition parameters.
    depth : int
        Octree depth of the Poisson solve (``CloudConfig.reconstruct_depth``).

    Returns
    -------
    Decomposition or None
        None when there is no surface, it fits no ball, or its ball volume disagrees
        with the cloud's (:func:`volumes_agree`).
    """
    from shapedb.mdbd.decomposition import decompose

    # in the decomposition's own frame, on a copy: the normals are estimated as the
    # decomposition estimated them, and ``geometry`` keeps no state from this call
    frame = np.asarray(decomposition.frame, dtype=np.float64)
    rotation, centre = frame[:3, :3], frame[:3, 3]
    try:
        surface = reconstruct(geometry.transformed(rotation.T, -rotation.T @ centre), depth=depth)
    except Exception as exc:  # noqa: BLE001 - a failed solve only costs the second feature
        log.warning("%s: no reconstruction (%s: %s)", geometry, type(exc).__name__, exc)
        return None
    if surface is None:
        return None
    try:
        found = decompose(surface, config=config)
    except ShapeDBError as exc:
        log.debug("%s: reconstruction not decomposed (%s)", geometry, exc)
        return None
    if found.n_balls == 0 or not volumes_agree(decomposition.radii, found.radii):
        return None
    return found
