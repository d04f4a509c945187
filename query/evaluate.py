"""Leave-one-out retrieval quality, with the Princeton Shape Benchmark's measures.

Every labelled shape queries all the others (itself excluded); the others are
ranked by decreasing similarity (or increasing distance), ties broken by ascending
id (a stable sort). With ``C`` the size of the query's class, ``G_i = 1`` when the
i-th result shares the query's label and ``hits(K) = G_1 + ... + G_K``
(Shilane et al., "The Princeton Shape Benchmark", SMI 2004):

* nearest neighbour  ``NN = G_1``;
* first tier         ``hits(C - 1) / (C - 1)``;
* second tier        ``hits(2 (C - 1)) / (C - 1)``;
* E-measure          ``2 / (1/P + 1/R)`` over the top 32 (``K = min(32, n - 1)``),
  ``P = hits(K) / K``, ``R = hits(K) / (C - 1)``; 0 when ``hits(K) = 0``;
* DCG                ``DCG_1 = G_1``, ``DCG_i = DCG_(i-1) + G_i / log2(i)`` over the
  whole ranking, divided by the ideal ``1 + sum_(j=2..C-1) 1 / log2(j)``.

Scores are the mean over queries ("micro-average", as PSB's tables report them) and
per class. Queries from classes of one shape are skipped (they have no relevant
result); unlabelled shapes (label None) are never queries nor relevant. The
precision-recall curve is averaged over queries at standard recall levels, using
interpolated precision (the largest precision at any recall >= the level).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from query.learn.labels import stored_labels
from shapedb.errors import QueryError
from shapedb.results import MEASURES, RetrievalScores  # defined there, re-exported here

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = ["RetrievalScores", "retrieval_scores", "evaluate", "MEASURES", "E_MEASURE_K"]

log = logging.getLogger(__name__)

E_MEASURE_K = 32
RECALL_LEVELS = np.linspace(0.0, 1.0, 11)
_CHUNK_CELLS = 8_000_000  # rows per chunk = this / n


def retrieval_scores(
    similarity: ArrayLike,
    labels: ArrayLike,
    *,
    ids: ArrayLike | None = None,
    distance: bool = False,
    recall_levels: ArrayLike = RECALL_LEVELS,
) -> RetrievalScores:
    """PSB measures from an all-pairs score matrix.

    Parameters
    ----------
    similarity : (n, n) float
        ``similarity[i, j]`` scores shape j as a result for query i (higher is
        better, or lower when ``distance``). The diagonal is ignored. NaN ranks last.
    labels : (n,)
        Class of each shape; None for unlabelled.
    ids : (n,) int, optional
        Shape ids, used to break ties (ascending); the row order when omitted.
    distance : bool
        The matrix holds distances (lower is better).
    recall_levels : (L,) float
        Recall levels of the precision-recall curve.

    Returns
    -------
    RetrievalScores
    """
    s = np.asarray(similarity, dtype=np.float64)
    n = len(s)
    if s.ndim != 2 or s.shape != (n, n):
        raise QueryError(f"expected a square matrix, got shape {s.shape}", source="similarity")

    def rows() -> Iterator[tuple[NDArray[np.intp], NDArray[np.float64]]]:
        step = max(1, _CHUNK_CELLS // max(n, 1))
        for lo in range(0, n, step):
            idx = np.arange(lo, min(lo + step, n))
            yield idx, s[idx]

    return _score(rows, labels, ids=ids, distance=distance, recall_levels=recall_levels)


def _score(
    rows: Callable[[], Iterator[tuple[NDArray[np.intp], NDArray[np.float64]]]],
    labels: ArrayLike,
    *,
    ids: ArrayLike | None,
    distance: bool,
    recall_levels: ArrayLike,
) -> RetrievalScores:
    """Core: ``rows()`` yields (row indices (b,), scores (b, n)) in any order."""
    lab = np.asarray(labels, dtype=object).ravel()
    n = len(lab)
    levels = np.asarray(recall_levels, dtype=np.float64).ravel()
    valid = np.array(
        [x is not None and not (isinstance(x, float) and np.isnan(x)) for x in lab], bool
    )
    names, codes = np.unique(lab[valid].astype(str), return_inverse=True)
    code = np.full(n, -1, np.int64)
    code[valid] = codes
    size = np.bincount(codes, minlength=len(names)) if n else np.zeros(0, np.int64)
    id_arr = np.arange(n, dtype=np.int64) if ids is None else np.asarray(ids, np.int64).ravel()
    if len(id_arr) != n or len(np.unique(id_arr)) != n:
        raise QueryError("ids must be unique and match the labels", source="ids")
    by_id = np.argsort(id_arr, kind="stable")  # column order that breaks ties by id
    k_e = min(E_MEASURE_K, max(n - 1, 1))

    disc = np.ones(max(n, 1))  # disc[i - 1] = DCG gain of rank i: 1, then 1 / log2(i)
    disc[1:] = 1.0 / np.log2(np.arange(2, max(n, 1) + 1))
    ideal = np.cumsum(disc)
    col_code = code[by_id]
    col_of = np.empty(n, np.int64)
    col_of[by_id] = np.arange(n)
    results: dict[str, list[float]] = {m: [] for m in (*MEASURES, "index")}
    pr_sum = np.zeros(len(levels))
    for idx, block in rows():
        c = code[idx]
        keep = (c >= 0) & (size[np.maximum(c, 0)] > 1)
        if not keep.any():
            continue
        idx, block, c = idx[keep], np.asarray(block, np.float64)[keep], c[keep]
        key = block[:, by_id] if distance else -block[:, by_id]  # columns in id order
        key[np.isnan(key)] = np.inf
        key[np.arange(len(idx)), col_of[idx]] = np.inf  # the query itself ranks last...
        ordered = np.sort(key, axis=1)  # values only: much faster than a stable argsort
        for row in range(len(idx)):
            me = col_of[idx[row]]
            cols = np.flatnonzero(col_code == c[row])
            cols = cols[cols != me]  # ...and is never counted
            ranks = _class_ranks(key[row], ordered[row], cols, me)
            results["index"].append(float(idx[row]))
            for m, value in _measures(ranks, disc, ideal, k_e).items():
                results[m].append(value)
            pr_sum += _precision_at(ranks, levels)

    per_query = {m: np.asarray(v, np.float64) for m, v in results.items()}
    per_query["index"] = per_query["index"].astype(np.int64)
    q = len(per_query["index"])
    if q == 0:
        log.warning("no query has a class of two or more labelled shapes: nothing to score")
    skipped = int(((code >= 0) & (size[np.maximum(code, 0)] <= 1)).sum()) if n else 0
    if skipped:
        log.info("skipped %d queries from classes of one shape", skipped)
    return RetrievalScores(
        queries=q,
        **{m: float(per_query[m].mean()) if q else float("nan") for m in MEASURES},
        per_class=_per_class(per_query, code, names),
        recall=levels,
        precision=pr_sum / q if q else np.full(len(levels), np.nan),
        per_query=per_query,
    )


def _class_ranks(
    key: NDArray[np.float64], ordered: NDArray[np.float64], cols: NDArray[np.intp], me: int
) -> NDArray[np.intp]:
    """Sorted 1-based ranks of a query's class members ``cols`` among the scores ``key``
    (columns in id order, ``ordered`` their sorted values); ties: smaller id first, the
    query ``me`` left out."""
    kv = key[cols]
    ranks = np.searchsorted(ordered, kv, side="left") + 1
    tied = np.searchsorted(ordered, kv, side="right") - ranks + 1 > 1
    for t in np.flatnonzero(tied):
        before = np.flatnonzero(key[: cols[t]] == kv[t])
        ranks[t] += len(before[before != me])
    return np.sort(ranks)


def _measures(
    ranks: NDArray[np.intp], disc: NDArray[np.float64], ideal: NDArray[np.float64], k_e: int
) -> dict[str, float]:
    """NN, first and second tier, E-measure and DCG of one query's sorted class ranks."""
    rel = len(ranks)  # C - 1
    h = np.count_nonzero(ranks <= k_e)
    return {
        "nn": float(ranks[0] == 1),
        "first_tier": np.count_nonzero(ranks <= rel) / rel,
        "second_tier": np.count_nonzero(ranks <= 2 * rel) / rel,
        "e_measure": 2.0 * h / (k_e + rel) if h else 0.0,
        "dcg": float(disc[ranks - 1].sum() / ideal[rel - 1]),
    }


def _precision_at(ranks: NDArray[np.intp], levels: NDArray[np.float64]) -> NDArray[np.float64]:
    """Interpolated precision (the max at recall >= r) at each recall level."""
    rel = len(ranks)
    prec = np.arange(1, rel + 1) / ranks
    rec = np.arange(1, rel + 1) / rel
    interp = np.maximum.accumulate(prec[::-1])[::-1]
    at = np.searchsorted(rec, levels - 1e-12, side="left")
    return np.where(at < rel, interp[np.minimum(at, rel - 1)], 0.0)


def _per_class(
    per_query: dict[str, NDArray[Any]], code: NDArray[np.int64], names: NDArray[Any]
) -> dict[str, dict[str, float]]:
    """Each class's query count and mean measures."""
    qc = code[per_query["index"]]
    out: dict[str, dict[str, float]] = {}
    for ci, name in enumerate(names):
        sel = qc == ci
        if sel.any():
            entry: dict[str, float] = {"queries": int(sel.sum())}
            entry.update({m: float(per_query[m][sel].mean()) for m in MEASURES})
            out[str(name)] = entry
    return out


def evaluate(
    db: StoreHandle,
    *,
    label: str = "label",
    method: str | Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
    plot: str | os.PathLike[str] | None = None,
    metric: Any = None,
) -> RetrievalScores:
    """Leave-one-out PSB measures of the store's shapes, grouped by ``label``.

    Parameters
    ----------
    db : shapedb.Database
    label : str
        Column of ``shapes`` (default ``"label"``) or a metadata key giving the class.
    method : None, "kernel" or callable, optional
        None / "kernel": the Eq. 3 kernel of the stored features (ranked by the
        equivalent Eq. 2 distance, so no precision is lost to ``exp``); a pair of a
        sparse cloud and a dense shape compares as the search compares it
        (:mod:`query.search.engine`: the nearest of own features, views and reconstructions). A callable receives the (n, d) features of the labelled shapes and
        returns an (n, n) similarity matrix.
    plot : path, optional
        Also save the precision-recall curve there (PNG).
    metric : LearnedMetric or path, optional
        Rank by a similarity fitted on labels (``db.fit_metric``, :mod:`query.learn.metric`)
        instead of the default kernel (with ``method`` None or "kernel" only). Scoring a
        metric on the shapes it was fitted on flatters it: fit on one store (or split)
        and evaluate on another.

    Returns
    -------
    RetrievalScores
    """
    learned = _checked_metric(db, metric, method)
    ids, labels, x = _labelled_features(db, label)
    if method is None or method == "kernel":
        rows = _kernel_distance_rows(db, ids, x, learned)
        scores = _score(rows, labels, ids=ids, distance=True, recall_levels=RECALL_LEVELS)
    elif callable(method):
        sim = np.asarray(method(x), dtype=np.float64)
        scores = retrieval_scores(sim, labels, ids=ids)
    else:
        raise QueryError("method must be None, 'kernel' or a callable", source=f"method={method!r}")
    log.info(
        "evaluate: %d queries, NN %.3f, 1-T %.3f, 2-T %.3f, E %.3f, DCG %.3f",
        scores.queries,
        scores.nn,
        scores.first_tier,
        scores.second_tier,
        scores.e_measure,
        scores.dcg,
    )
    if plot is not None:
        scores.plot(plot)
    return scores


def _checked_metric(db: StoreHandle, metric: Any, method: Any) -> Any:
    """The learned metric to rank by (None for the default), checked against the store.

    Raises :class:`QueryError` when a metric comes with a callable ``method``.
    """
    from query.learn.metric import as_metric

    learned = as_metric(metric)
    if learned is not None:
        learned.check(db.config)
        if callable(method):
            raise QueryError(
                "a metric weighs the kernel: not with a callable method", source="metric"
            )
    return learned


def _labelled_features(
    db: StoreHandle, label: str
) -> tuple[NDArray[np.int64], NDArray[Any], NDArray[np.float64]]:
    """Ids (n,), labels (n,) and stored features (n, d) of the labelled shapes.

    Ids and features are aligned on ids (a commit may happen between the two reads);
    unlabelled shapes are left out.
    """
    ids_all, labels_all = stored_labels(db, label)
    fid, feats = db.store.features()
    if not np.array_equal(fid, ids_all):  # a commit happened in between: align on ids
        common, a, b = np.intersect1d(ids_all, fid, return_indices=True)
        ids_all, labels_all, fid, feats = common, labels_all[a], fid[b], feats[b]
    keep = np.array([x is not None for x in labels_all], bool)
    if not keep.all():
        log.info("evaluate: %d unlabelled shapes left out", int((~keep).sum()))
    return ids_all[keep], labels_all[keep], np.asarray(feats[keep], np.float64)


def _kernel_distance_rows(
    db: StoreHandle, ids: NDArray[np.int64], x: NDArray[np.float64], learned: Any
) -> Callable[[], Iterator[tuple[NDArray[np.intp], NDArray[np.float64]]]]:
    """Chunks of rows of the Eq. 2 distance matrix between the shapes ``ids``, as search ranks.

    The features ``x`` (n, d) are weighed by the kernel's weights (times the learned
    metric's); a pair of a sparse cloud and a dense shape is as far apart as the
    nearest of own-own and either side's second feature (its view or reconstruction;
    its own feature where it has none) against the other's own (:mod:`query.search.engine`).
    A store with a re-ranking stage (``RerankConfig``, :mod:`query.search.rerank`) and neither
    sparse clouds nor views ranks as its search does: each row holds the ranks of
    :func:`query.search.rerank.rerank_candidates` over the stored-distance order. Each call of the returned function yields ``(row indices, (rows, n) distances)``.
    """
    from scipy.spatial.distance import cdist

    from query.search.stage import scorer_for
    from shapedb.signature.kernel import weights

    n = len(ids)
    w = weights(db.config)
    if learned is not None:
        w = w * learned.dim_weights()
    xw = x * w
    sparse = np.isin(ids, db.store.sparse_ids())
    vw = None
    if sparse.any():
        vid, views = db.store.features(view=True)
        pos = np.searchsorted(vid, ids)
        vw = np.asarray(views[pos], np.float64) * w

    stage = None if vw is not None or db.config.cloud.view_cells else scorer_for(db.config)

    def rows() -> Iterator[tuple[NDArray[np.intp], NDArray[np.float64]]]:
        if stage is not None:
            arrays = None
            if db.config.stores_light_fields:
                from query.search.rerank_lightfield import stored_arrays

                arrays = stored_arrays(db, preload=True)
            yield from _reranked_rows(
                stage, db.config, ids, x, np.asarray(w, np.float64), arrays=arrays
            )
            return
        step = max(1, _CHUNK_CELLS // max(n, 1))
        for lo in range(0, n, step):
            idx = np.arange(lo, min(lo + step, n))
            d = cdist(xw[idx], xw, "cityblock")
            if vw is not None:
                one = sparse[idx, None] != sparse[None, :]
                near = np.minimum(cdist(xw[idx], vw, "cityblock"), cdist(vw[idx], xw, "cityblock"))
                d = np.where(one, np.minimum(d, near), d)
            yield idx, d

    return rows


def _reranked_rows(
    scorer: Any,
    config: Any,
    ids: NDArray[np.int64],
    x: NDArray[np.float64],
    w: NDArray[np.float64],
    *,
    arrays: Any = None,
) -> Iterator[tuple[NDArray[np.intp], NDArray[np.float64]]]:
    """Rows of ranks (0 = first) in the order a search with the re-ranking stage returns.

    Stored distances are computed as the index re-ranks them (``|x - q| @ w`` in
    float64), ordered with ties by ascending id, and handed to
    :func:`query.search.rerank.rerank_candidates` whole, the query among them, as a search
    for every shape would see them; a scorer's extra candidates (the field vectors'
    nearest, :mod:`query.search.field_index`) are taken among the shapes ``ids`` and placed
    after the first ``K`` as a search places them (:func:`query.search.rerank.with_extras`).
    """
    from query.search.rerank import Candidates, extra_candidates, rerank_candidates, with_extras

    n, dim = x.shape
    sorter = np.argsort(ids)
    step = max(1, _CHUNK_CELLS // max(n * dim, 1))
    for lo in range(0, n, step):
        idx = np.arange(lo, min(lo + step, n))
        d = np.abs(x[None, :, :] - x[idx, None, :]) @ w  # (b, n), as FeatureIndex re-ranks
        order = np.lexsort((np.broadcast_to(ids, d.shape), d), axis=-1)
        batch = Candidates(
            ids[idx], x[idx], ids[order], x[order], w, np.take_along_axis(d, order, 1), config,
            arrays, None, int(scorer.tuning.candidates),
        )  # fmt: skip
        extra = extra_candidates(scorer, batch, ids)
        if extra is not None:
            at = np.minimum(np.searchsorted(ids, extra, sorter=sorter), n - 1)
            batch = with_extras(batch, extra, x[sorter[at]])
        got, _ = rerank_candidates(scorer, batch, n)
        cols = sorter[np.searchsorted(ids, got, sorter=sorter)]
        ranks = np.empty((len(idx), n))
        np.put_along_axis(
            ranks, cols, np.broadcast_to(np.arange(n, dtype=np.float64), cols.shape), 1
        )
        yield idx, ranks
