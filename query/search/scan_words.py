"""A one-sided scan's words against the stored shapes' view words.

A store that keeps view words (``Config.stores_view_words``: each record's
``view_words`` column, :func:`shapedb.signature.view_words.view_words`) holds the words
of every shape seen from the same fixed directions. :func:`nearest_by_view_words` ranks
the stored shapes by their least chi-square distance to a scan's words
(:func:`shapedb.signature.view_words.scan_words`) over their views, reading the column
:data:`BLOCK` shapes at a time from its memory-mapped cache
(:mod:`query.search.array_cache`): each block is ranked by the largest Bhattacharyya
coefficient over its views (``1 - BC`` lies between half the chi-square distance and all
of it), the best :data:`SHORTLIST` x ``n`` overall are then ranked exactly. Memory stays
bounded at any store size; the time is linear in it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from query.search.array_cache import best_rows, open_column
from shapedb.signature.surface_words import WORDS
from shapedb.signature.view_words import VIEWS, view_words_distances

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = [
    "VIEW_WORDS_COLUMN",
    "BLOCK",
    "SHORTLIST",
    "stored_view_words",
    "nearest_by_view_words",
]

VIEW_WORDS_COLUMN = "view_words"
#: Stored shapes whose view words are read at a time (about 84 MB of float64 rows).
BLOCK = 2048
#: Shapes kept per one asked for by the approximate ranking before the exact one.
SHORTLIST = 4


def stored_view_words(
    db: StoreHandle, ids: NDArray[np.int64] | None = None
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The stored shapes' view words: ids (m,) int64 ascending and their rows
    (m, VIEWS * WORDS). ``ids``: the shapes asked for (default: every alive shape); shapes
    stored without view words are left out. From the column cache, else from the store."""
    width = VIEWS * WORDS
    cache = open_column(db, VIEW_WORDS_COLUMN)
    if cache is not None:
        want = cache.ids if ids is None else np.intersect1d(cache.ids, np.asarray(ids, np.int64))
        rows = cache.get(want) if len(want) else np.zeros((0, width))
        if rows is None:
            return np.zeros(0, np.int64), np.zeros((0, width))
    else:
        table = db.store.shapes(
            ["id", VIEW_WORDS_COLUMN], ids=None if ids is None else [int(i) for i in ids]
        )
        got = table.column(VIEW_WORDS_COLUMN).to_pylist()
        want = np.asarray(table.column("id").to_pylist(), np.int64)
        rows = np.array(
            [w if w is not None and len(w) == width else [np.nan] * width for w in got],
            np.float64,
        ).reshape(len(want), width)
        order = np.argsort(want, kind="stable")
        want, rows = want[order], rows[order]
    keep = np.isfinite(rows).all(axis=1) if len(rows) else np.zeros(0, bool)
    return np.asarray(want, np.int64)[keep], np.asarray(rows, np.float64)[keep]


def nearest_by_view_words(
    db: StoreHandle, words: ArrayLike, n: int, allowed: NDArray[np.int64] | None = None
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The (at most) ``n`` stored shapes nearest the scan's ``words`` (WORDS,) over their
    views: ids (m,) int64, nearest first (ties by ascending id), and their distances (m,)
    (:func:`~shapedb.signature.view_words.view_words_distances`, in [0, 1]).

    ``allowed``: the ids that may be returned (default: every alive shape). Empty when
    the store keeps no view words.
    """
    q = np.asarray(words, np.float64).ravel()
    if n <= 0 or q.shape != (WORDS,):
        return np.zeros(0, np.int64), np.zeros(0)
    cache = open_column(db, VIEW_WORDS_COLUMN)
    if cache is None:  # no cache to stream from (a read-only store): its rows at once
        ids, rows = stored_view_words(db, allowed)
    else:
        ids = cache.ids if allowed is None else np.intersect1d(cache.ids, allowed)
        root = np.sqrt(np.maximum(q, 0.0))

        def bhattacharyya(rows: NDArray[np.float64]) -> NDArray[np.float64]:
            views = np.sqrt(np.maximum(rows, 0.0)).reshape(-1, VIEWS, WORDS)
            return np.asarray((views @ root).max(axis=1))

        best_ids = best_rows(
            cache, ids, SHORTLIST * n, bhattacharyya, block=BLOCK, width=VIEWS * WORDS
        )
        ids, rows = stored_view_words(db, best_ids)
    near = view_words_distances(q, rows)
    order = np.lexsort((ids, near))[:n]
    return np.asarray(ids[order], np.int64), np.asarray(near[order], np.float64)
