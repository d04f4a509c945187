"""Partial-to-whole search: the stored shapes that *contain* the query.

A one-sided scan (what one depth camera sees), a cropped or broken model, or a part cut
from an assembly is only part of a stored shape, and its whole-shape feature
(:mod:`query.search.engine`) resembles none. The partial path compares the query's
parts instead, one neighbourhood subgraph ``G[N(v, K)]`` per ball v (the part kernel of
:mod:`query.parts.match`, :class:`shapedb.config.part.PartConfig`), with the store's part
index (:mod:`query.parts.index`, built on demand as ``db.match`` does):

1. *Votes*: each of the query's :data:`VOTING_PARTS` largest balls' neighbourhoods asks
   the index for its :data:`SHAPES_PER_PART` nearest shapes (best node per shape, exact
   re-rank); a shape's vote is the volume-weighted sum of the similarities it got.
2. *Score*: the :data:`CANDIDATES` (at least ``k``) best-voted shapes are scored
   exactly: for every query neighbourhood, the best similarity ``exp(-lam * d)`` it
   finds among all the shape's neighbourhoods; the score is the mean of those, each
   query neighbourhood weighted by its centre ball's volume (``r^3``). A shape holding
   every part of the query scores high, one holding a few parts low.

``partial=True`` takes the partial path for every query of a call; ``False`` the whole
one. ``None`` (the default) lets the search decide: a point cloud whose normals lie on
one side (a depth camera's scan, :func:`shapedb.geometry.view.viewing_direction`) is
matched by its silhouette against the stored light fields' views
(:mod:`query.search.view_search`, ``path="view"``), everything else by the whole path.
Measured on one-sided views and halves of generated shapes, the partial path found their
class no more often than the whole-shape search (docs/studies.md, "Partial-to-whole
search"), so it runs on request.

A triangle mesh is closed over its cuts before its parts are read
(:meth:`~shapedb.geometry.mesh.TriangleMesh.capped`, where that makes it a closed solid):
cut open, a solid part's mesh bounds a shell one cell thick whose parts are a hollow
shape's. Validation halves (``bench.sets.scans.cropped_mesh``) by the partial path, NN:
parts 0.083 -> 0.438 (the whole path 0.188), CAPOD 0.267 -> 0.367 (whole 0.383). The
whole path keeps a mesh's holes: an open basin is a basin.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from query.search.catalog import catalog
from query.search.engine import checked_k
from query.search.engine import search_batch as whole_search_batch
from query.search.view_search import view_search
from shapedb.config.part import PartConfig
from shapedb.errors import QueryError
from shapedb.geometry.mesh import TriangleMesh
from shapedb.results import Hit

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = [
    "search",
    "search_batch",
    "partial_search",
    "VOTING_PARTS",
    "SHAPES_PER_PART",
    "CANDIDATES",
]

#: Query neighbourhoods (the largest balls first) that vote for candidate shapes; with the
#: two below, a partial search cost 0.32-0.65 of a whole one (72 and 200 generated shapes).
VOTING_PARTS = 32
#: Nearest shapes each voting neighbourhood asks the part index for.
SHAPES_PER_PART = 16
#: Best-voted shapes scored exactly (``k`` more when k is larger): on 200 generated shapes
#: the ranking equalled scoring every shape exactly (same class NN on 63 cut and scanned queries).
CANDIDATES = 32


def search(
    db: StoreHandle,
    query: Any,
    *,
    k: int = 10,
    where: str | None = None,
    metric: Any = None,
    partial: bool | None = None,
) -> list[Hit]:
    """The k stored shapes most like ``query``, by the whole shape or by its parts.

    Parameters
    ----------
    db : shapedb.Database
    query : as :func:`query.search.engine.search` takes
        A raw feature vector has no parts: only the whole path takes it.
    k : int
        Number of hits.
    where : str, optional
        SQL predicate over the ``shapes`` table restricting the shapes returned.
    metric : LearnedMetric or path, optional
        A learned whole-shape similarity (whole path only).
    partial : bool or None
        True: the partial path; False: the whole path (:mod:`query.search.engine`);
        None (the default): the view path for a one-sided point cloud in a store with
        light fields, else the whole path (see the module docstring).

    Returns
    -------
    list of Hit
        Best first; each hit's ``path`` says which search found it.

    Raises
    ------
    QueryError
        A malformed query, ``k``, ``where`` or ``partial``; ``partial=True`` with a
        feature vector or a ``metric``.
    NotFoundError
        Unknown shape id or name.
    """
    return search_batch(db, [query], k=k, where=where, metric=metric, partial=partial)[0]


def search_batch(
    db: StoreHandle, queries: Sequence[Any], *, k: int = 10, where: str | None = None,
    metric: Any = None, partial: bool | None = None,
) -> list[list[Hit]]:  # fmt: skip
    """:func:`search` for many queries: the whole-path ones in one engine call.

    Returns one list of hits per query, in the order of ``queries``.
    """
    if partial is not None and not isinstance(partial, bool):
        raise QueryError("partial must be True, False or None", source=f"partial={partial!r}")
    if partial is False or isinstance(queries, (str, bytes, os.PathLike)):
        return _whole(db, queries, k, where, metric)  # the engine checks the sequence
    if isinstance(queries, np.ndarray) and queries.ndim == 2:
        queries = list(queries)
    if not isinstance(queries, Sequence):
        return _whole(db, queries, k, where, metric)
    if partial is None:
        return _whole_or_view(db, queries, k, where, metric)
    if metric is not None:
        raise QueryError(
            "a learned metric weighs whole-shape features: search by parts without it",
            source="metric",
        )
    return [partial_search(db, _load(q), k=k, where=where) for q in queries]


def _whole(
    db: StoreHandle, queries: Any, k: int, where: str | None, metric: Any
) -> list[list[Hit]]:
    found: list[list[Hit]] = whole_search_batch(db, queries, k=k, where=where, metric=metric)
    return found


def _whole_or_view(
    db: StoreHandle, queries: Sequence[Any], k: int, where: str | None, metric: Any
) -> list[list[Hit]]:
    """One-sided clouds by their silhouette (:mod:`query.search.view_search`) where the
    store keeps light fields and no learned metric is asked for; the rest by the whole
    path, in one engine call."""
    from shapedb.geometry.pointcloud import PointCloud
    from shapedb.geometry.view import viewing_direction

    out: list[list[Hit] | None] = [None] * len(queries)
    whole: list[int] = []
    loaded = list(queries)
    allowed: NDArray[np.int64] | None = None
    for i, query in enumerate(queries):
        if metric is None and not isinstance(query, (np.ndarray, list, tuple, int, np.integer)):
            loaded[i] = _load(query)
        direction = viewing_direction(loaded[i]) if isinstance(loaded[i], PointCloud) else None
        if direction is not None:
            if allowed is None and where is not None:
                from query.sql import allowed_ids

                allowed = allowed_ids(db, where)
            out[i] = view_search(db, loaded[i], direction, k=checked_k(k), allowed=allowed)
        if out[i] is None:
            whole.append(i)
    if whole:
        found = _whole(db, [loaded[i] for i in whole], k, where, metric)
        for i, hits in zip(whole, found, strict=True):
            out[i] = hits
    return [hits if hits is not None else [] for hits in out]


def _load(query: Any) -> Any:
    """A query file loaded into its Geometry (as the engine would); anything else as is."""
    path = None
    if isinstance(query, os.PathLike):
        path = Path(query)
    elif isinstance(query, str):
        try:
            path = Path(query) if Path(query).is_file() else None
        except (OSError, ValueError):
            path = None
    if path is None:
        return query
    import ingest  # the public API only: ingest.load(path) -> Geometry

    return ingest.load(path)


def partial_search(
    db: StoreHandle,
    query: Any,
    *,
    k: int = 10,
    where: str | None = None,
    config: PartConfig | None = None,
) -> list[Hit]:
    """The k stored shapes that hold the most of ``query``'s parts, best first.

    Parameters
    ----------
    db : shapedb.Database
    query : id, name, path, Geometry, Decomposition, ShapeRecord or ContactGraph
        Decomposed with the store's configuration; a triangle mesh with holes is
        closed over them first where that makes it a solid (:meth:`TriangleMesh.capped`:
        a cropped or broken part).
    k : int
    where : str, optional
        SQL predicate over ``shapes`` restricting the shapes searched.
    config : PartConfig, optional
        Part kernel and the part index used (default ``PartConfig()``, ``db.match``'s).

    Returns
    -------
    list of Hit
        ``path="partial"``; ``similarity`` the volume-weighted mean best similarity of
        the query's neighbourhoods in the shape, in (0, 1]; ties by ascending id.
    """
    from query.parts.match import resolve
    from query.parts.store_index import open_parts_index
    from shapedb.signature.subgraph import neighbourhood_features, part_config

    if isinstance(query, (np.ndarray, list, tuple)):
        raise QueryError(
            "a feature vector has no parts: search by parts needs a shape", source="query vector"
        )
    k = checked_k(k)
    cfg = part_config(config)
    if isinstance(query, TriangleMesh):
        query = query.capped()  # a part cut from a solid is that solid's part, not a shell
    graph = resolve(db, query, part=cfg).graph
    if not graph.n_nodes:
        raise QueryError("the query has no balls: nothing to search by parts", source="query")
    index = open_parts_index(db, cfg)
    allowed = None
    if where is not None:
        from query.sql import allowed_ids

        allowed = allowed_ids(db, where)
    volume = np.asarray(graph.radii, np.float64) ** 3
    parts = _Parts(neighbourhood_features(graph, cfg), volume / volume.sum(), float(cfg.kernel.lam))
    shapes = _candidates(index, parts, k, allowed)
    if not len(shapes):
        return []
    scores = np.array([_score(index, parts, int(s)) for s in shapes])
    order = np.lexsort((shapes, -scores))[:k]
    names = catalog(db, db.store.version).lookup(shapes[order])
    hits = []
    for sid, score, found in zip(shapes[order], scores[order], names, strict=True):
        if found is None:  # deleted by a commit made while we searched
            continue
        distance = float(-np.log(score) / parts.lam) if score > 0 else float("inf")
        hits.append(Hit(int(sid), found[0], found[1], float(score), distance, "partial"))
    return hits


@dataclass(frozen=True)
class _Parts:
    """The query's parts: (n, d) neighbourhood features, (n,) volume weights summing to 1,
    and the part kernel's ``lam``."""

    feats: NDArray[np.float64]
    volume: NDArray[np.float64]
    lam: float


def _candidates(
    index: Any, parts: _Parts, k: int, allowed: NDArray[np.int64] | None
) -> NDArray[np.int64]:
    """The best-voted shapes (ids, at most ``max(CANDIDATES, k)``)."""
    voters = np.argsort(-parts.volume, kind="stable")[:VOTING_PARTS]
    votes: dict[int, float] = {}
    for v in voters.tolist():
        found = index.search(parts.feats[v], SHAPES_PER_PART, per_shape=1, allowed=allowed)
        for sid, d in zip(found[0].tolist(), found[2].tolist(), strict=True):
            votes[sid] = votes.get(sid, 0.0) + float(parts.volume[v] * np.exp(-parts.lam * d))
    if not votes:
        return np.zeros(0, np.int64)
    ids = np.fromiter(votes, np.int64, len(votes))
    got = np.fromiter(votes.values(), np.float64, len(votes))
    return ids[np.lexsort((ids, -got))[: max(CANDIDATES, k)]]


def _score(index: Any, parts: _Parts, sid: int) -> float:
    """Volume-weighted mean over the query's neighbourhoods of their best similarity in
    shape ``sid`` (its every node, exact weighted L1 distances)."""
    from scipy.spatial.distance import cdist

    w = index.weights
    stored = index.features_of(sid)
    if not len(stored):
        return 0.0
    # the stored rows are float32: quantise the query alike (an identical part scores 1)
    q = parts.feats.astype(np.float32).astype(np.float64)
    best = cdist(q * w, stored * w, metric="cityblock").min(axis=1)
    return float(parts.volume @ np.exp(-parts.lam * best))
