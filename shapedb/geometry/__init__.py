"""Representations of a solid and their signed distance fields.

Every representation implements :class:`Geometry` (a signed distance and a bounding box):
analytic implicit solids and CSG, triangle meshes (robust to soups, holes and flipped
faces), point clouds, voxel grids, and the thickened solids of sheets. The grid and the
field's inside are here too; the decomposition (:mod:`shapedb.mdbd`) reads nothing else.
"""

from __future__ import annotations

from shapedb.geometry.base import Geometry, Grid, Transformed
from shapedb.geometry.complement import Complement
from shapedb.geometry.implicit import (
    Box,
    Capsule,
    Cylinder,
    Difference,
    Implicit,
    Intersection,
    Sphere,
    Torus,
    Union,
)
from shapedb.geometry.inside import Inside, field_inside
from shapedb.geometry.mesh import TriangleMesh
from shapedb.geometry.pointcloud import PointCloud
from shapedb.geometry.sheet import LocallyThickened, Thickened
from shapedb.geometry.voxels import VoxelGrid

__all__ = [
    "Geometry",
    "Grid",
    "Transformed",
    "Implicit",
    "Sphere",
    "Box",
    "Capsule",
    "Cylinder",
    "Torus",
    "Union",
    "Intersection",
    "Difference",
    "TriangleMesh",
    "PointCloud",
    "VoxelGrid",
    "Thickened",
    "LocallyThickened",
    "Complement",
    "Inside",
    "field_inside",
]
