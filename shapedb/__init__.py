"""shapedb: representation-agnostic 3D shape retrieval on the Maximal Disjoint Ball Decomposition.

Pipeline: representation (:mod:`shapedb.geometry`) -> SDF -> MDBD and contact graph
(:mod:`shapedb.mdbd`) -> signatures (:mod:`shapedb.signature`) -> store
(:mod:`shapedb.store`) -> index and query (:mod:`query`, ``shapedb.connect(path)``).

``import shapedb`` stays light: the configuration and the errors load eagerly; every other
name (the representations, the decomposition with numba, the store with pyarrow, the
database facade) loads from its subpackage on first use.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

from shapedb.config.core import CloudConfig, Config, DescriptorConfig, KernelConfig, MDBDConfig
from shapedb.config.part import PartConfig
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

__version__ = "0.1.0"

_GEOMETRY = frozenset(
    {"Geometry", "Grid", "Implicit", "Sphere", "Box", "Capsule", "Cylinder", "Torus", "Union"}
    | {"Intersection", "Difference", "TriangleMesh", "PointCloud", "VoxelGrid"}
)
_MDBD = frozenset({"decompose", "Decomposition", "ContactGraph", "contact_edges"})
_SIGNATURE = frozenset({"features", "features_batch", "weights", "distance"})
_RESULTS = frozenset(
    {"IngestReport", "StoreInfo", "Hit", "PartMatch", "RetrievalScores", "Classification"}
    | {"Metric", "Classifier"}
)
_FACADE = frozenset({"connect", "Database"})

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
    "kernel",  # the module shapedb.signature.kernel (Eq. 1-3); the function is kernel.kernel
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
    """Every name but the configuration and the errors, imported on first use.

    ``import a.b as m`` rather than ``from a import b``: the latter asks this function first.
    """
    module: ModuleType
    if name in _GEOMETRY:
        import shapedb.geometry as geometry

        module = geometry
    elif name in _MDBD:
        import shapedb.mdbd as mdbd

        module = mdbd
    elif name in _SIGNATURE:
        import shapedb.signature as signature

        module = signature
    elif name == "kernel":
        import shapedb.signature.kernel as kernel

        return kernel
    elif name in _RESULTS:
        import shapedb.results as results

        module = results
    elif name in _FACADE:
        # the facade sits on the top floor, beside the query engine it calls
        import query.database as database

        module = database
    elif name == "examples":
        import shapedb.examples as examples

        return examples
    else:
        raise AttributeError(f"module 'shapedb' has no attribute {name!r}")
    value = getattr(module, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
