"""The query package's public names, and that importing it stays light."""

from __future__ import annotations

import subprocess
import sys

import query


def test_public_all():
    assert sorted(query.__all__) == [
        "FeatureIndex",
        "Hit",
        "LearnedMetric",
        "PartGeometry",
        "PartIndex",
        "PartMatch",
        "RetrievalScores",
        "build_index",
        "fit_metric",
        "match_pairs",
        "open_index",
        "open_parts_index",
        "part_geometry",
        "query_features",
        "retrieval_scores",
    ]
    assert all(hasattr(query, name) for name in query.__all__)


def test_import_is_light():
    code = (
        "import sys, query, query.search.index, query.search.engine, query.sql, query.evaluate, query.learn.metric; "
        "print(sorted(m for m in ('faiss', 'duckdb', 'matplotlib', 'torch') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_modules_are_not_shadowed():
    """No package re-exports a name that is also one of its modules (``import a.b as m``
    would bind the name, not the module)."""
    import importlib
    import pkgutil

    import shapedb

    for package in (shapedb, query):
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            if info.name.endswith("__main__"):
                continue
            parent, _, leaf = info.name.rpartition(".")
            module = importlib.import_module(info.name)
            assert getattr(importlib.import_module(parent), leaf) is module, info.name
