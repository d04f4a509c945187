"""The public API of ``shapedb``: ``__all__`` pinned exactly, one module of result types."""

from __future__ import annotations

import dataclasses
import inspect
import typing

import pytest

import shapedb
from query.database import Database
from shapedb import results

PUBLIC = {
    # configuration
    "Config", "MDBDConfig", "KernelConfig", "DescriptorConfig", "CloudConfig", "PartConfig",
    # errors
    "ShapeDBError", "InvalidShapeError", "EmptyGeometryError", "NonFiniteGeometryError",
    "DegenerateGeometryError", "LoadError", "UnsupportedFormatError", "ConfigError",
    "StoreError", "StoreLockedError", "NotFoundError", "QueryError", "NotFittedError",
    "MissingDependencyError",
    # geometry
    "Geometry", "Grid", "Implicit", "Sphere", "Box", "Capsule", "Cylinder", "Torus", "Union",
    "Intersection", "Difference", "TriangleMesh", "PointCloud", "VoxelGrid",
    # decomposition, graph, kernel
    "decompose", "Decomposition", "ContactGraph", "contact_edges", "features",
    "features_batch", "weights", "distance", "kernel",
    # database, its results, and examples
    "connect", "Database", "IngestReport", "StoreInfo", "Hit", "PartMatch", "RetrievalScores",
    "Classification", "Metric", "Classifier", "examples", "__version__",
}  # fmt: skip


def test_all_is_pinned_exactly_and_every_name_resolves() -> None:
    assert len(shapedb.__all__) == len(set(shapedb.__all__))
    assert set(shapedb.__all__) == PUBLIC
    for name in shapedb.__all__:
        assert getattr(shapedb, name) is not None, name
    assert callable(
        shapedb.signature.kernel.kernel
    )  # shapedb.signature.kernel is the module (Eq. 1-3)


def test_result_types_live_in_one_module_and_are_re_exported_where_they_were() -> None:
    import ingest.pipeline
    import query
    import query.evaluate
    import query.learn.classify
    import query.parts.match
    import query.search.engine

    assert ingest.pipeline.IngestReport is results.IngestReport is shapedb.IngestReport
    assert query.search.engine.Hit is query.Hit is results.Hit
    assert query.parts.match.PartMatch is query.PartMatch is results.PartMatch
    assert query.evaluate.RetrievalScores is query.RetrievalScores is results.RetrievalScores
    assert query.evaluate.MEASURES is results.MEASURES
    assert query.learn.classify.Classification is results.Classification
    for cls in (results.IngestReport, results.Hit, results.PartMatch, results.Classification):
        assert dataclasses.is_dataclass(cls) and cls.__module__ == "shapedb.results"


def test_the_learned_metric_is_a_metric() -> None:
    from query.learn.metric import LearnedMetric

    metric = LearnedMetric(blocks=(("a", 2),), weights=(1.0,), fingerprint="x")
    assert isinstance(metric, results.Metric)


def _methods() -> list[tuple[str, typing.Callable[..., object]]]:
    return [
        (name, fn)
        for name, fn in inspect.getmembers(Database, inspect.isfunction)
        if not name.startswith("_")
    ]


@pytest.mark.parametrize("name", [name for name, _ in _methods()])
def test_every_database_method_is_explicitly_typed(name: str) -> None:
    fn = getattr(Database, name)
    sig = inspect.signature(fn)
    assert sig.return_annotation is not inspect.Signature.empty, name
    assert "Any" not in str(sig.return_annotation), name
    for p in sig.parameters.values():
        assert p.kind is not inspect.Parameter.VAR_KEYWORD, (name, p.name)
        assert p.kind is not inspect.Parameter.VAR_POSITIONAL, (name, p.name)
        if p.name != "self":
            assert p.annotation is not inspect.Parameter.empty, (name, p.name)
