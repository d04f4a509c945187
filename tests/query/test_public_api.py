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
        "on_commit",
        "open_index",
        "open_parts_index",
        "part_geometry",
        "query_features",
        "retrieval_scores",
        "search",
        "search_batch",
    ]
    assert all(hasattr(query, name) for name in query.__all__)


def test_import_is_light():
    code = (
        "import sys, query, query.index, query.engine, query.sql, query.evaluate, query.metric; "
        "print(sorted(m for m in ('faiss', 'duckdb', 'matplotlib', 'torch') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_modules_are_not_shadowed():
    import importlib

    for name in ("index", "engine", "sql", "evaluate"):
        assert (
            getattr(query, name, importlib.import_module(f"query.{name}")).__name__
            == f"query.{name}"
        )
