"""Retrieval over a shapedb store: feature index, search, SQL and evaluation.

The functions whose first argument is a :class:`query.database.Database` are what
``db.search``, ``db.search_batch``, ``db.sql`` and ``db.evaluate`` call. Importing this package is light: faiss, DuckDB and
matplotlib are imported only when an index, a SQL connection or a plot is used.

``query.search.engine.search``, ``query.sql.sql`` and ``query.evaluate.evaluate`` are
deliberately not re-exported here: the names would shadow their modules (``import query.sql as m`` would bind
the function). Use ``db.sql(...)`` / ``db.evaluate(...)`` or import them from their
modules.
"""

from __future__ import annotations

from query.evaluate import RetrievalScores, retrieval_scores
from query.learn.metric import LearnedMetric, fit_metric
from query.parts.index import PartIndex
from query.parts.match import PartGeometry, PartMatch, match_pairs, part_geometry
from query.parts.store_index import open_parts_index
from query.search.engine import Hit, query_features
from query.search.index import FeatureIndex, build_index, open_index

__all__ = [
    "FeatureIndex",
    "Hit",
    "LearnedMetric",
    "PartGeometry",
    "PartIndex",
    "PartMatch",
    "match_pairs",
    "open_parts_index",
    "part_geometry",
    "RetrievalScores",
    "build_index",
    "fit_metric",
    "open_index",
    "query_features",
    "retrieval_scores",
]
