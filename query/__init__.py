"""Retrieval over a shapedb store: feature index, search, SQL and evaluation.

The functions whose first argument is a :class:`shapedb.Database` are the
``shapedb.extensions`` entry points behind ``db.search``, ``db.search_batch``,
``db.sql`` and ``db.evaluate``. Importing this package is light: faiss, DuckDB and
matplotlib are imported only when an index, a SQL connection or a plot is used.
"""

from __future__ import annotations

from query.engine import Hit, query_features, search, search_batch
from query.evaluate import RetrievalScores, evaluate, retrieval_scores
from query.index import FeatureIndex, build_index, open_index
from query.sql import sql

__all__ = [
    "FeatureIndex",
    "Hit",
    "RetrievalScores",
    "build_index",
    "evaluate",
    "open_index",
    "query_features",
    "retrieval_scores",
    "search",
    "search_batch",
    "sql",
]
