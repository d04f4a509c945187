"""Whole-shape search: the faiss index, its candidates, and the exact re-ranking stage.

``db.search`` calls :func:`query.search.engine.search`, which takes the index's
candidates (:mod:`query.search.index`) and re-ranks them (:mod:`query.search.rerank`).
"""

from __future__ import annotations

from query.search.engine import MAX_K, query_features
from query.search.index import FeatureIndex, build_index, open_index

__all__ = [
    "FeatureIndex",
    "build_index",
    "open_index",
    "query_features",
    "MAX_K",
]
