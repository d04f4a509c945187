"""Retrieval over a shapedb store: feature index, search, SQL and evaluation.

The functions whose first argument is a :class:`shapedb.Database` are the
``shapedb.extensions`` entry points behind ``db.search``, ``db.search_batch``,
``db.sql`` and ``db.evaluate``. Importing this package is light: faiss, DuckDB and
matplotlib are imported only when an index, a SQL connection or a plot is used.

``query.sql.sql`` and ``query.evaluate.evaluate`` are deliberately not re-exported
here: the names would shadow their modules (``import query.sql as m`` would bind
the function). Use ``db.sql(...)`` / ``db.evaluate(...)`` or import them from their
modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from query.engine import Hit, query_features, search, search_batch
from query.evaluate import RetrievalScores, retrieval_scores
from query.index import FeatureIndex, build_index, open_index
from query.metric import LearnedMetric, fit_metric
from query.parts_index import PartIndex, open_parts_index
from query.substructure import PartGeometry, PartMatch, match_pairs, part_geometry

if TYPE_CHECKING:
    from shapedb.database import Database

__all__ = [
    "FeatureIndex",
    "Hit",
    "LearnedMetric",
    "PartGeometry",
    "PartIndex",
    "PartMatch",
    "match_pairs",
    "on_commit",
    "open_parts_index",
    "part_geometry",
    "RetrievalScores",
    "build_index",
    "fit_metric",
    "open_index",
    "query_features",
    "retrieval_scores",
    "search",
    "search_batch",
]


def on_commit(db: Database, *args: object, **kwargs: object) -> None:
    """Store commit hook (entry point ``on_commit``): bring every built index up to date.

    Whole-shape and part indexes that were already built are updated, and so are the
    light field spreads of a ``"lightfield"`` store that pools them
    (:mod:`query.lightfield_spread`) and the shared-neighbour lists of one whose stage
    reads them (:mod:`query.lightfield_neighbours`); a store never searched gets them
    lazily on first use.
    """
    from query import index, parts_index

    index.on_commit(db, *args, **kwargs)
    parts_index.on_commit(db, *args, **kwargs)
    if db.config.rerank.scorer == "lightfield":
        from query import lightfield_neighbours, lightfield_spread
        from query.rerank_lightfield import LightFieldFusion, stored_arrays

        lightfield_spread.on_commit(db, stored_arrays(db))
        lightfield_neighbours.on_commit(db, stored_arrays(db), LightFieldFusion(db.config))
