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
3. *Words*, in a store with surface words: a part keeps its whole's local surface, so
   the query's words, read at a ladder of scales (:mod:`query.parts.part_words`), rank
   the stored shapes; the :data:`CANDIDATES` nearest join the voted ones, and the
   candidates are ordered by their ranks by words and by parts fused
   (:data:`WORD_OFFSET`, :data:`PARTS_WEIGHT`). The words lead (a half's words found its
   class far more often than its parts); the parts tell a solid from a hollow shell
   with the same faces.

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
shape's (its words are read from its own faces, the cut left open). The whole path keeps
a mesh's holes: an open basin is a basin. The figures: docs/results.md, "Scans and
clouds".
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

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
    "WORD_OFFSET",
    "PARTS_WEIGHT",
    "PartialCandidates",
    "partial_candidates",
    "fused_similarity",
    "WORDS_ONE_SIDED",
    "WORDS_WHOLE",
    "words_ratio",
    "is_one_sided_cloud",
]

#: Query neighbourhoods (the largest balls first) that vote for candidate shapes; with the
#: two below, a partial search cost 0.32-0.65 of a whole one (72 and 200 generated shapes).
VOTING_PARTS = 32
#: Nearest shapes each voting neighbourhood asks the part index for.
SHAPES_PER_PART = 16
#: Best-voted shapes scored exactly (``k`` more when k is larger): on 200 generated shapes
#: the ranking equalled scoring every shape exactly (same class NN on 63 cut and scanned queries).
#: In a store with words, as many again are the nearest by words.
CANDIDATES = 32
#: The reciprocal ranks' offset and the parts' weight against the words' (1) in the
#: fused order: the best validation halves' NN and 1-T summed over CAPOD, parts and
#: enclosures of a grid of offsets 2-16 and weights 0-1 (``python -m
#: bench.studies.part_words``).
WORD_OFFSET = 4.0
PARTS_WEIGHT = 0.5
#: The words' ratio of a cloud (:func:`words_ratio`: how much nearer its flattened words
#: lie to a stored view's than its words to a stored whole's) below which it is one-sided
#: and at or above which it is not, whatever its geometry says; between the two, its
#: geometry decides (:func:`~shapedb.geometry.view.viewing_direction`). On validation
#: clouds (CAPOD and parts, ``python -m bench.studies.view_words``): one-sided scans the
#: geometry calls one-sided 0.76 at most, whole clouds it calls one-sided 1.05 at least
#: (:data:`WORDS_WHOLE` lies between); one-sided scans it misses 0.21-0.90, whole clouds it
#: rightly passes 0.46 at least (:data:`WORDS_ONE_SIDED` lies below: 7 of the 19 missed
#: scans are taken, none of the whole clouds).
WORDS_ONE_SIDED = 0.45
WORDS_WHOLE = 0.9


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
    """One-sided clouds by their silhouette and view words (:mod:`query.search.view_search`)
    where the store keeps light fields and no learned metric is asked for; the rest by
    the whole path, in one engine call (:func:`is_one_sided_cloud` decides; a one-sided
    cloud without a viewing direction is ranked by its words alone)."""
    from shapedb.geometry.pointcloud import PointCloud
    from shapedb.geometry.view import viewing_direction

    out: list[list[Hit] | None] = [None] * len(queries)
    whole: list[int] = []
    loaded = list(queries)
    allowed: NDArray[np.int64] | None = None
    for i, query in enumerate(queries):
        if metric is None and not isinstance(query, (np.ndarray, list, tuple, int, np.integer)):
            loaded[i] = _load(query)
        cloud = loaded[i] if isinstance(loaded[i], PointCloud) else None
        direction = viewing_direction(cloud) if cloud is not None else None
        if cloud is not None and is_one_sided_cloud(db, cloud, direction, metric is None):
            if allowed is None and where is not None:
                from query.sql import allowed_ids

                allowed = allowed_ids(db, where)
            out[i] = view_search(db, cloud, direction, k=checked_k(k), allowed=allowed)
        if out[i] is None:
            whole.append(i)
    if whole:
        found = _whole(db, [loaded[i] for i in whole], k, where, metric)
        for i, hits in zip(whole, found, strict=True):
            out[i] = hits
    return [hits if hits is not None else [] for hits in out]


def words_ratio(db: StoreHandle, points: ArrayLike) -> float | None:
    """How much a cloud's words look like one side of a stored shape rather than a whole.

    ``points`` (n, 3): the cloud. The least distance of its flattened words
    (:func:`~shapedb.signature.view_words.scan_words`) to a stored view's words, over the
    least distance of its words (:func:`~shapedb.signature.surface_words.surface_words`) to
    a stored shape's surface words: well below 1 for a one-sided scan, about 1 and above
    for a cloud around a whole surface. None in a store without view words or surface
    words, and for a cloud without features.
    """
    from query.parts.part_words import nearest_by_words, stored_words
    from query.search.scan_words import nearest_by_view_words
    from shapedb.signature.surface_words import surface_words, words_distance
    from shapedb.signature.view_words import scan_words

    flat = scan_words(points)
    whole = surface_words(points)
    if not flat.any() or not whole.any():
        return None
    _, near_view = nearest_by_view_words(db, flat, 1)
    nearest = nearest_by_words(db, whole[None, :], 1)
    if not len(near_view) or not len(nearest):
        return None
    _, rows = stored_words(db, nearest)
    if not len(rows):
        return None
    near_whole = float(words_distance(whole, rows).min())
    return float(near_view[0]) / near_whole if near_whole > 0 else float("inf")


def is_one_sided_cloud(
    db: StoreHandle, cloud: Any, direction: NDArray[np.float64] | None, words: bool = True
) -> bool:
    """Whether the view path takes ``cloud`` (a PointCloud): its viewing ``direction``
    (:func:`~shapedb.geometry.view.viewing_direction`, None when its geometry does not
    call it one-sided) and, in a store with view words and when ``words``, its
    :func:`words_ratio`: below :data:`WORDS_ONE_SIDED` always, at or above
    :data:`WORDS_WHOLE` never, between as its geometry says."""
    if not (words and db.config.stores_view_words):
        return direction is not None
    ratio = words_ratio(db, cloud.points)
    if ratio is None:
        return direction is not None
    if ratio < WORDS_ONE_SIDED:
        return True
    return direction is not None and ratio < WORDS_WHOLE


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
    """The k stored shapes that hold the most of ``query``, best first.

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
        ``path="partial"``, best first, ties by ascending id. ``similarity`` in (0, 1]:
        in a store with surface words, the fused reciprocal ranks by words and by parts
        over their largest value (1: first by both), ``distance`` its ``-log``; in a
        store without, the volume-weighted mean best similarity of the query's
        neighbourhoods in the shape, ``distance`` ``-log(similarity) / lam``.
    """
    found = partial_candidates(db, query, k=k, where=where, config=config)
    if not len(found.ids):
        return []
    if found.words is None:
        similarity = found.parts
        with np.errstate(divide="ignore"):
            distance = -np.log(similarity) / found.lam
    else:
        similarity = fused_similarity(found.parts, found.words)
        distance = np.abs(np.log(similarity))  # similarity <= 1: no -0.0
    order = np.lexsort((found.ids, -similarity))[:k]
    names = catalog(db, db.store.version).lookup(found.ids[order])
    hits = []
    for sid, sim, dist, name in zip(
        found.ids[order], similarity[order], distance[order], names, strict=True
    ):
        if name is None:  # deleted by a commit made while we searched
            continue
        hits.append(Hit(int(sid), name[0], name[1], float(sim), float(dist), "partial"))
    return hits


@dataclass(frozen=True)
class PartialCandidates:
    """A partial search's candidates with what ranks them, before they are fused.

    Attributes
    ----------
    ids : (c,) int64
        Candidate shape ids, ascending.
    parts : (c,) float64
        Each one's parts score in [0, 1]: the volume-weighted mean best similarity of the
        query's neighbourhoods in the shape.
    words : (c,) float64 or None
        Each one's least chi-square distance by words (inf: a shape without words); None
        in a store without words or for a query without a surface.
    lam : float
        The part kernel's ``lam``.
    """

    ids: NDArray[np.int64]
    parts: NDArray[np.float64]
    words: NDArray[np.float64] | None
    lam: float


def partial_candidates(
    db: StoreHandle,
    query: Any,
    *,
    k: int = 10,
    where: str | None = None,
    config: PartConfig | None = None,
) -> PartialCandidates:
    """The candidates :func:`partial_search` orders (same arguments): the
    :data:`CANDIDATES` (at least ``k``) best-voted shapes and, in a store with words,
    as many nearest by words, each scored both ways.

    Raises
    ------
    QueryError
        A feature vector, or a query without balls.
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
    capped = query.capped() if isinstance(query, TriangleMesh) else query
    # a part cut from a solid is that solid's part, not a shell (its words: its own faces)
    model = resolve(db, capped, part=cfg)
    graph = model.graph
    if not graph.n_nodes:
        raise QueryError("the query has no balls: nothing to search by parts", source="query")
    index = open_parts_index(db, cfg)
    allowed = None
    if where is not None:
        from query.sql import allowed_ids

        allowed = allowed_ids(db, where)
    volume = np.asarray(graph.radii, np.float64) ** 3
    lam = float(cfg.kernel.lam)
    parts = _Parts(neighbourhood_features(graph, cfg), volume / volume.sum(), lam)
    shapes = _candidates(index, parts, k, allowed)
    ladder = _query_words(db, query, model)
    near = None
    if ladder is not None:
        shapes, near = _with_words(db, shapes, ladder, k, allowed)
    else:
        shapes = np.sort(shapes)
    scores = np.array([_score(index, parts, int(s)) for s in shapes], np.float64)
    return PartialCandidates(shapes, scores, near, lam)


def fused_similarity(
    parts: NDArray[np.float64],
    words: NDArray[np.float64],
    *,
    offset: float = WORD_OFFSET,
    weight: float = PARTS_WEIGHT,
) -> NDArray[np.float64]:
    """(c,) similarities in (0, 1] of candidates from their parts scores (c,) (higher
    first) and words distances (c,) (lower first), by their ranks among the candidates:
    ``(1 / (o + rank_w) + v / (o + rank_p)) * o / (1 + v)``, ranks from 0, ``o`` the
    ``offset``, ``v`` the parts' ``weight`` (>= 0); 1 for a shape first both ways."""
    from query.search.rerank import list_ranks

    o, v = float(offset), float(weight)
    fused = 1.0 / (o + list_ranks(np.asarray(words, np.float64)))
    fused += v / (o + list_ranks(-np.asarray(parts, np.float64)))
    return np.asarray(fused * o / (1.0 + v), np.float64)


def _query_words(db: StoreHandle, query: Any, model: Any) -> NDArray[np.float64] | None:
    """The query's words at each of :data:`~query.parts.part_words.PART_REACHES`
    (a geometry), its stored words (a stored shape), or None (no words in the store, or
    nothing to draw them from)."""
    from query.parts.part_words import part_words, stored_words
    from shapedb.errors import DegenerateGeometryError
    from shapedb.geometry.base import Geometry
    from shapedb.store.schema import ShapeRecord

    if not db.config.stores_surface_words:
        return None
    if isinstance(query, Geometry) and model.decomposition is not None:
        try:
            return part_words(query, model.decomposition.spacing).astype(np.float64)
        except DegenerateGeometryError:
            return None
    if isinstance(query, ShapeRecord) and query.surface_words is not None:
        return np.asarray(query.surface_words, np.float64)[None, :]
    if model.id is not None:
        ids, rows = stored_words(db, np.array([model.id], np.int64))
        return rows if len(ids) else None
    return None


def _with_words(
    db: StoreHandle,
    shapes: NDArray[np.int64],
    words: NDArray[np.float64],
    k: int,
    allowed: NDArray[np.int64] | None,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The voted shapes and the :data:`CANDIDATES` (at least ``k``) nearest by words,
    ascending ids, with each one's words distance (inf: a shape without words)."""
    from query.parts.part_words import nearest_by_words, stored_words, words_distances

    every = np.union1d(shapes, nearest_by_words(db, words, max(CANDIDATES, k), allowed))
    ids, rows = stored_words(db, every)
    out = np.full(len(every), np.inf)
    out[np.searchsorted(every, ids)] = words_distances(words, rows)
    return every, out


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
