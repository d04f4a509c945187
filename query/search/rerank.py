"""An exact re-ranking stage after the index: candidates in, a scorer's order out.

The faiss index (:mod:`query.search.index`) proposes, per query, the ``K =
RerankConfig.candidates`` nearest shapes by the stored vector's L1 distance (exact
on a flat index, ties by ascending id). A *scorer* then gives each candidate an
exact distance of its own, and the candidates are re-ranked by it (ties by ascending
id). Past the K-th, results keep the stored-vector order and distance. Search
(:mod:`query.search.engine`) and evaluation (:mod:`query.evaluate`) both go through
:func:`rerank_candidates`, so they rank alike.

The scorer is an object the caller passes (:func:`query.search.stage.scorer_for` makes
the store's: the light field stage of :mod:`query.search.rerank_lightfield`, or none). A
scorer sees one batch of candidate lists, :class:`Candidates`: the queries' and
candidates' stored vectors, their ids and their stored distances, and returns one
distance per candidate. A scorer that needs a per-record array of its own (not in the
stored vector) reads it by the candidates' ids; a query that is not a stored shape has
``query_ids`` -1 and its array must come from the query itself.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from query.search.tuning import PRODUCT, StageTuning

if TYPE_CHECKING:
    from shapedb.config.core import Config

__all__ = [
    "Candidates",
    "ArrayReader",
    "Scorer",
    "rerank_candidates",
    "extra_candidates",
    "with_extras",
    "stage_batch",
    "search",
    "list_ranks",
]

log = logging.getLogger(__name__)

#: Queries scored together (bounds the (queries, candidates, d) temporaries).
_CHUNK = 16
_NO_ID = np.iinfo(np.int64).max


def list_ranks(d: NDArray[np.float64]) -> NDArray[np.float64]:
    """(c,) rank of each entry of ``d`` (c,), 0 first, ties in list order."""
    r = np.empty(len(d))
    r[np.argsort(d, kind="stable")] = np.arange(len(d), dtype=np.float64)
    return r


@dataclass(frozen=True)
class Candidates:
    """A batch of candidate lists, as a scorer receives them.

    Attributes
    ----------
    query_ids : (q,) int64
        Stored id of each query; -1 for a query that is not a stored shape.
    queries : (q, d) float64
        The queries' stored vectors (raw, unweighted).
    ids : (q, c) int64
        Candidate ids, nearest first by the stored distance; -1 pads.
    features : (q, c, d) float64
        The candidates' stored vectors; zeros where padded.
    weights : (d,) float64
        Per-number weights of the stored distance (the kernel's, times a learned
        metric's): ``distance = |x - q| @ weights``.
    distances : (q, c) float64
        Stored distances of the candidates; inf where padded.
    config : Config
        The store's configuration.
    arrays : ArrayReader, optional
        Reads a per-record array column by ids (e.g. ``"light_field"``): ``arrays(name,
        ids)`` -> (m, ...) float64, NaN rows for records without it, or None when the
        store has no such column. None: no per-record arrays.
    query_arrays : mapping, optional
        Per-query arrays computed from the queries themselves, by column name: (q, ...)
        float64, NaN rows where a query has none (e.g. a stored query, read by id).
    head : int, optional
        Entries of each list the stage re-ranks: version 4's ``K`` nearest and the
        scorer's extra candidates after them (:func:`with_extras`); None: the stage's
        ``K`` (:attr:`query.search.tuning.StageTuning.candidates`).
    """

    query_ids: NDArray[np.int64]
    queries: NDArray[np.float64]
    ids: NDArray[np.int64]
    features: NDArray[np.float64]
    weights: NDArray[np.float64]
    distances: NDArray[np.float64]
    config: Config
    arrays: ArrayReader | None = None
    query_arrays: Mapping[str, NDArray[np.float64]] | None = None
    head: int | None = None

    @property
    def valid(self) -> NDArray[np.bool_]:
        """(q, c) bool: a real candidate (not padding)."""
        return (self.ids >= 0) & np.isfinite(self.distances)


class ArrayReader(Protocol):
    """Reads a per-record array column: ``(name, ids (m,) int64) -> (m, ...) float64 | None``."""

    def __call__(self, name: str, ids: NDArray[np.int64]) -> NDArray[np.float64] | None: ...


class Scorer(Protocol):
    """An exact distance for candidates: ``score(batch) -> (q, c)`` float64, lower is nearer.

    Padded entries (``batch.valid`` False) may hold anything: they are dropped.

    A scorer may also propose candidates of its own beyond the index's ``K`` nearest,
    through an optional method ``extra_candidates(batch, allowed) -> (q, e) int64 | None``
    (ids, -1 pads; ``allowed`` the ids a search is restricted to, or None): the stage
    re-ranks them after the ``K`` (:func:`with_extras`).
    """

    tuning: StageTuning

    def score(self, batch: Candidates) -> NDArray[np.float64]: ...


def extra_candidates(
    scorer: Scorer, batch: Candidates, allowed: Any = None
) -> NDArray[np.int64] | None:
    """The scorer's proposed extra candidates (q, e), or None (it proposes none)."""
    propose = getattr(scorer, "extra_candidates", None)
    if propose is None:
        return None
    got = propose(batch, allowed)
    return None if got is None else np.asarray(got, np.int64).reshape(len(batch.ids), -1)


def with_extras(
    batch: Candidates, extra_ids: NDArray[np.int64], extra_features: NDArray[np.float64]
) -> Candidates:
    """``batch`` with extra candidates re-ranked after its first ``K`` (the union).

    Each list becomes: its first ``K = batch.head or PRODUCT.candidates`` entries,
    then the extras not among them in stored-distance order (``|x - q| @ weights``, ties
    by ascending id; -1 / inf pads up to ``e``), then the rest of the list without the
    extras. ``head`` of the result covers the ``K`` and the ``e`` extra slots.

    Parameters
    ----------
    batch : Candidates
    extra_ids : (q, e) int64
        Proposed ids, -1 pads; ids among the first ``K`` or repeated are dropped.
    extra_features : (q, e, d) float64
        Their stored vectors (anything where padded).
    """
    n_k = int(batch.head if batch.head is not None else PRODUCT.candidates)
    n_k = min(n_k, batch.ids.shape[1])
    head = batch.ids[:, :n_k]
    ex = np.asarray(extra_ids, np.int64)
    q, e = ex.shape
    new = ex >= 0
    for row in range(q):
        _, first = np.unique(ex[row], return_index=True)
        once = np.zeros(e, bool)
        once[first] = True
        new[row] &= once & ~np.isin(ex[row], head[row])
    feats = np.asarray(extra_features, np.float64).reshape(q, e, -1)
    d = np.abs(feats - batch.queries[:, None, :]) @ batch.weights
    d = np.where(new, d, np.inf)
    order = np.lexsort((np.where(new, ex, _NO_ID), d), axis=-1)
    ex_d = np.take_along_axis(d, order, 1)
    ex_i = np.where(np.isfinite(ex_d), np.take_along_axis(ex, order, 1), -1)
    ex_f = np.where(
        np.isfinite(ex_d)[..., None], np.take_along_axis(feats, order[..., None], 1), 0.0
    )
    rest_i = batch.ids[:, n_k:].copy()
    rest_d = batch.distances[:, n_k:].copy()
    rest_f = batch.features[:, n_k:].copy()
    for row in range(q):
        dup = np.isin(rest_i[row], ex_i[row][ex_i[row] >= 0]) & (rest_i[row] >= 0)
        rest_i[row, dup], rest_d[row, dup], rest_f[row, dup] = -1, np.inf, 0.0
    return dataclasses.replace(
        batch,
        ids=np.concatenate([head, ex_i, rest_i], axis=1),
        features=np.concatenate([batch.features[:, :n_k], ex_f, rest_f], axis=1),
        distances=np.concatenate([batch.distances[:, :n_k], ex_d, rest_d], axis=1),
        head=n_k + e,
    )


def rerank_candidates(
    scorer: Scorer, batch: Candidates, k: int
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The first ``K`` candidates of each list re-ranked by ``scorer``, then the rest.

    Parameters
    ----------
    scorer : Scorer
    batch : Candidates
        Lists of at least ``K = batch.head`` (default ``PRODUCT.candidates``)
        entries where the store holds that many (stored-distance order, then any
        extras, :func:`with_extras`); entries past ``K`` keep their order and stored
        distance. Padding inside a list is squeezed out.
    k : int
        Results wanted per query.

    Returns
    -------
    ids : (q, k) int64
        -1 pads.
    distances : (q, k) float64
        The scorer's distance for the first ``K``, the stored one after; inf pads.
    """
    n_k = int(batch.head if batch.head is not None else PRODUCT.candidates)
    head = dataclasses.replace(
        batch,
        ids=batch.ids[:, :n_k],
        features=batch.features[:, :n_k],
        distances=batch.distances[:, :n_k],
    )
    d = np.asarray(scorer.score(head), np.float64)
    valid = head.valid
    d = np.where(valid, d, np.inf)
    key = np.where(valid, head.ids, _NO_ID)
    order = np.lexsort((key, d), axis=-1)
    ids = np.concatenate([np.take_along_axis(head.ids, order, 1), batch.ids[:, n_k:]], axis=1)
    dist = np.concatenate([np.take_along_axis(d, order, 1), batch.distances[:, n_k:]], axis=1)
    real = (ids >= 0) & np.isfinite(dist)
    if not real.all():  # pads inside the lists (the extras' slots): real entries first
        squeeze = np.argsort(~real, axis=1, kind="stable")
        ids = np.take_along_axis(ids, squeeze, 1)
        dist = np.where(
            np.take_along_axis(real, squeeze, 1), np.take_along_axis(dist, squeeze, 1), np.inf
        )
    out_i = np.full((len(ids), k), -1, np.int64)
    out_d = np.full((len(ids), k), np.inf)
    m = min(k, ids.shape[1])
    out_i[:, :m], out_d[:, :m] = ids[:, :m], dist[:, :m]
    out_i[~np.isfinite(out_d)] = -1
    return out_i, out_d


def stage_batch(
    index: Any,
    queries: NDArray[np.float64],
    ids: NDArray[np.int64],
    distances: NDArray[np.float64],
    *,
    config: Config,
    scorer: Scorer,
    query_ids: NDArray[np.int64],
    allowed: Any = None,
    arrays: ArrayReader | None = None,
    query_arrays: Mapping[str, NDArray[np.float64]] | None = None,
) -> Candidates:
    """The candidate lists of some queries as the stage receives them (:func:`search`).

    Parameters
    ----------
    index : FeatureIndex
        Fitted; the candidates' stored vectors are read from it.
    queries : (q, d) float64
        The queries' stored vectors.
    ids, distances : (q, c) int64, (q, c) float64
        The index's lists (``index.search`` of ``queries``, at least ``K`` each).
    config : Config
    scorer : Scorer
        Its extra candidates (within ``allowed`` and the index's live ids) are placed
        after the first ``K`` (:func:`with_extras`).
    query_ids : (q,) int64
        Stored ids of the queries, -1 for one that is not stored.
    allowed, arrays, query_arrays : optional
        As :func:`search`'s.

    Returns
    -------
    Candidates
        ``head`` covers the entries the stage re-ranks.
    """
    pos = index.lookup(np.where(ids >= 0, ids, -1).ravel()).reshape(ids.shape)
    feats = np.asarray(index.features_)[np.maximum(pos, 0)].astype(np.float64)
    feats[pos < 0] = 0.0
    batch = Candidates(
        np.asarray(query_ids, np.int64), np.asarray(queries, np.float64), ids, feats,
        index.weights_, distances, config, arrays, query_arrays, int(scorer.tuning.candidates),
    )  # fmt: skip
    extra = extra_candidates(scorer, batch, allowed)
    if extra is not None:
        at = index.lookup(np.where(extra >= 0, extra, -1).ravel()).reshape(extra.shape)
        extra = np.where(at >= 0, extra, -1)
        ex_f = np.asarray(index.features_)[np.maximum(at, 0)].astype(np.float64)
        batch = with_extras(batch, extra, ex_f)
    return batch


def search(
    index: Any,
    queries: NDArray[np.float64],
    k: int,
    *,
    config: Config,
    query_ids: NDArray[np.int64] | None = None,
    allowed: Any = None,
    scorer: Scorer | None = None,
    arrays: ArrayReader | None = None,
    query_arrays: Mapping[str, NDArray[np.float64]] | None = None,
    stored_distances: bool = False,
    candidates: tuple[NDArray[np.int64], NDArray[np.float64]] | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The index's search followed by the re-ranking stage ``scorer``.

    Parameters
    ----------
    index : FeatureIndex
        Fitted (:mod:`query.search.index`); its weights are the stored distance's.
    queries : (q, d) float64
        Stored vectors of the queries.
    k : int
        Results per query.
    config : Config
        The store's configuration.
    query_ids : (q,) int64, optional
        Stored id of each query, -1 (the default) for one that is not stored.
    allowed : (m,) int, optional
        Restrict the candidates to these ids (an exhaustive scan).
    scorer : Scorer, optional
        The stage (:func:`query.search.stage.scorer_for`); None: the index's order. Its
        extra candidates
        (``extra_candidates``, :class:`Scorer`) are re-ranked after the ``K``, within
        ``allowed`` and the index's live ids.
    arrays, query_arrays : optional
        Per-record and per-query arrays for the scorer (:class:`Candidates`).
    stored_distances : bool
        Return each result's stored distance (the index's) instead of the scorer's;
        the order is the scorer's either way.
    candidates : (ids, distances), optional
        The queries' lists in stored-distance order, (q, c) int64 and float64, -1 / inf
        pads, with at least ``max(k, K)`` entries where the store holds that many: used
        instead of the index's search of ``queries`` (a sparse cloud's list merges its
        reconstruction's, :mod:`query.search.engine`).

    Returns
    -------
    ids, distances : (q, k) int64, (q, k) float64
        As :meth:`FeatureIndex.search`; the first ``K`` re-ranked by the scorer.
    """
    if scorer is None or not len(np.asarray(index.features_)):
        if candidates is not None:
            return _first(candidates, k)
        return index.search(queries, k, allowed=allowed)  # type: ignore[no-any-return]
    q = np.atleast_2d(np.asarray(queries, np.float64))
    qid = np.full(len(q), -1, np.int64) if query_ids is None else np.asarray(query_ids, np.int64)
    wanted = max(int(k), int(scorer.tuning.candidates))
    cand, dist = index.search(q, wanted, allowed=allowed) if candidates is None else candidates
    out_i = np.full((len(q), k), -1, np.int64)
    out_d = np.full((len(q), k), np.inf)
    for s in range(0, len(q), _CHUNK):
        c = cand[s : s + _CHUNK]
        batch = stage_batch(
            index, q[s : s + _CHUNK], c, dist[s : s + _CHUNK], config=config, scorer=scorer,
            query_ids=qid[s : s + _CHUNK], allowed=allowed, arrays=arrays,
            query_arrays=None if query_arrays is None else {
                n: a[s : s + _CHUNK] for n, a in query_arrays.items()},
        )  # fmt: skip
        got_i, got_d = rerank_candidates(scorer, batch, k)
        out_i[s : s + len(c)], out_d[s : s + len(c)] = got_i, got_d
        if stored_distances:  # each result's stored distance, from its list
            for row in range(len(c)):
                keep = got_i[row] >= 0
                listed = batch.ids[row]
                order = np.argsort(listed, kind="stable")
                at = order[np.searchsorted(listed, got_i[row][keep], sorter=order)]
                out_d[s + row][keep] = batch.distances[row][at]
    return out_i, out_d


def _first(
    lists: tuple[NDArray[np.int64], NDArray[np.float64]], k: int
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The first ``k`` entries of lists ((q, c) ids and distances), -1 / inf padded to ``k``."""
    ids, dist = (np.atleast_2d(np.asarray(a)) for a in lists)
    out_i = np.full((len(ids), k), -1, np.int64)
    out_d = np.full((len(ids), k), np.inf)
    m = min(k, ids.shape[1])
    out_i[:, :m], out_d[:, :m] = ids[:, :m], dist[:, :m]
    return out_i, out_d
