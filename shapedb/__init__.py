"""shapedb: representation-agnostic 3D shape retrieval on the Maximal Disjoint Ball Decomposition.

Pipeline: representation -> SDF -> MDBD (:func:`decompose`) -> contact graph
(:class:`ContactGraph`) -> features (:func:`features`, the paper's Eq. 1) -> store
-> index -> query (``shapedb.connect(path)``).

``import shapedb`` stays light: only numpy/scipy-backed modules load eagerly; the
decomposition (numba), the representations (trimesh/open3d/igl), the store
(pyarrow) and the examples load on first use of one of their names.
"""

from __future__ import annotations

import importlib
from typing import Any

from shapedb import kernel  # the module: shapedb.kernel.kernel is Eq. 3
from shapedb.config import (
    CloudConfig,
    Config,
    DescriptorConfig,
    KernelConfig,
    MDBDConfig,
    PartConfig,
)
from shapedb.errors import (
    ConfigError,
    DegenerateGeometryError,
    EmptyGeometryError,
    InvalidShapeError,
    LoadError,
    MissingDependencyError,
    NonFiniteGeometryError,
    NotFittedError,
    NotFoundError,
    QueryError,
    ShapeDBError,
    StoreError,
    StoreLockedError,
    UnsupportedFormatError,
)
from shapedb.geometry import Geometry, Grid
from shapedb.graph import ContactGraph, contact_edges
from shapedb.implicit import (
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
from shapedb.kernel import distance, features, features_batch, weights
from shapedb.results import (
    Classification,
    Classifier,
    Hit,
    IngestReport,
    Metric,
    PartMatch,
    RetrievalScores,
    StoreInfo,
)

__version__ = "0.1.0"

# name -> module that defines it, imported on first attribute access
_LAZY = {
    "decompose": "shapedb.mdbd",
    "Decomposition": "shapedb.mdbd",
    "TriangleMesh": "shapedb.mesh",
    "PointCloud": "shapedb.pointcloud",
    "VoxelGrid": "shapedb.voxels",
    "connect": "shapedb.database",
    "Database": "shapedb.database",
    "examples": "shapedb.examples",
}

__all__ = [
    # configuration and errors
    "Config",
    "MDBDConfig",
    "KernelConfig",
    "DescriptorConfig",
    "CloudConfig",
    "PartConfig",
    "ShapeDBError",
    "InvalidShapeError",
    "EmptyGeometryError",
    "NonFiniteGeometryError",
    "DegenerateGeometryError",
    "LoadError",
    "UnsupportedFormatError",
    "ConfigError",
    "StoreError",
    "StoreLockedError",
    "NotFoundError",
    "QueryError",
    "NotFittedError",
    "MissingDependencyError",
    # geometry
    "Geometry",
    "Grid",
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
    # decomposition, graph, kernel
    "decompose",
    "Decomposition",
    "ContactGraph",
    "contact_edges",
    "features",
    "features_batch",
    "weights",
    "distance",
    "kernel",  # the module shapedb.kernel (Eq. 1-3); the function is shapedb.kernel.kernel
    # database, its results, and examples
    "connect",
    "Database",
    "IngestReport",
    "StoreInfo",
    "Hit",
    "PartMatch",
    "RetrievalScores",
    "Classification",
    "Metric",
    "Classifier",
    "examples",
    "__version__",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'shapedb' has no attribute {name!r}")
    mod = importlib.import_module(module)
    value = mod if module.endswith("." + name) else getattr(mod, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
