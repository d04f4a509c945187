"""A part's surface words against the stored wholes': what the partial path ranks first.

A cropped or broken model keeps the local surface of its whole: the words
(:mod:`shapedb.signature.surface_words`) of half a shape are near the whole's when both
are read at the same scale. The part's scale against its whole is unknown, so the
part's words are read at each of :data:`PART_REACHES` (the whole's bounding radius in
units of the part's, :func:`~shapedb.signature.surface_words.surface_features`'s
``reach``) and a stored shape's distance is the least chi-square distance over them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = [
    "PART_REACHES",
    "BLOCK",
    "part_words",
    "stored_words",
    "words_distances",
    "nearest_by_words",
]

#: The wholes' bounding radii, in units of the part's, at which a part's words are read.
#: Validation halves (``bench.sets.scans.cropped_mesh``) NN by the least distance over
#: these against reach 1 alone: CAPOD 0.883 -> 0.983, parts 0.708 -> 0.792, enclosures
#: 0.643 -> 0.679 (``python -m bench.studies.part_words``).
PART_REACHES = (1.0, 1.2, 1.4, 1.7, 2.0)
#: Stored shapes whose words are read at a time when a whole store is ranked (about
#: 64 MB of float64 rows): memory stays bounded at any store size.
BLOCK = 32768
#: Shapes kept per asked for by the first, approximate ranking (the Bhattacharyya
#: coefficient, which bounds the chi-square distance within a factor of 2) before the exact.
_SHORTLIST = 4


def part_words(geometry: Any, spacing: float) -> NDArray[np.float32]:
    """(len(PART_REACHES), WORDS) float32: ``geometry``'s words read at each reach.

    ``spacing`` (model units) is the grid an implicit or voxel geometry's surface is
    drawn at (:func:`~shapedb.signature.surface_words.surface_points`).

    Raises
    ------
    DegenerateGeometryError
        The geometry has no surface to sample.
    """
    from shapedb.signature.surface_words import surface_points, surface_words

    points = surface_points(geometry, spacing)
    return np.stack([surface_words(points, reach=r) for r in PART_REACHES])


def stored_words(
    db: StoreHandle, ids: NDArray[np.int64] | None = None
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The stored shapes' words: ids (m,) int64 ascending and their words (m, WORDS).

    ``ids``: the shapes asked for (default: every alive shape). Shapes without words
    (stored before the store kept them, or not stored) are left out. Read from the
    memory-mapped column cache (:mod:`query.search.array_cache`), else from the store.
    """
    from query.search.array_cache import open_column
    from query.search.word_fusion import WORDS_COLUMN

    cache = open_column(db, WORDS_COLUMN)
    if cache is not None:
        want = cache.ids if ids is None else np.unique(np.asarray(ids, np.int64))
        rows = cache.get(want)
        if rows is None:
            return np.zeros(0, np.int64), np.zeros((0, 0))
    else:
        table = db.store.shapes(["id", WORDS_COLUMN], ids=None if ids is None else list(ids))
        got = table.column(WORDS_COLUMN).to_pylist()
        want = np.asarray(table.column("id").to_pylist(), np.int64)
        width = max((len(w) for w in got if w is not None), default=0)
        rows = np.array([w if w is not None else [np.nan] * width for w in got], np.float64)
        order = np.argsort(want, kind="stable")
        want, rows = want[order], rows.reshape(len(want), width)[order]
    keep = np.isfinite(rows).all(axis=1) if rows.size else np.zeros(len(want), bool)
    return np.asarray(want, np.int64)[keep], rows[keep]


def words_distances(ladder: ArrayLike, words: ArrayLike) -> NDArray[np.float64]:
    """(m,) least chi-square distance of each stored row of ``words`` (m, WORDS) to the
    rows of ``ladder`` (r, WORDS), :func:`part_words`' reaches or one whole's words."""
    from shapedb.signature.surface_words import words_distance

    stored = np.asarray(words, np.float64)
    if not len(stored):
        return np.zeros(0)
    q = np.atleast_2d(np.asarray(ladder, np.float64))
    return np.min(np.stack([words_distance(row, stored) for row in q]), axis=0)


def nearest_by_words(
    db: StoreHandle, ladder: ArrayLike, n: int, allowed: NDArray[np.int64] | None = None
) -> NDArray[np.int64]:
    """Ids of the (at most) ``n`` stored shapes nearest ``ladder`` (r, WORDS) by
    :func:`words_distances`, nearest first, ties by ascending id.

    ``allowed``: the ids that may be returned (default: every alive shape). The store's
    words are read :data:`BLOCK` shapes at a time from the column cache; each block is
    ranked by the largest Bhattacharyya coefficient ``sum sqrt(q * h)`` over the rungs
    (one matrix product; ``1 - BC`` lies between half the chi-square distance and all of
    it), the best ``4 n`` overall are then ranked exactly. Shapes without words are left out.
    """
    from query.search.array_cache import best_rows, open_column
    from query.search.word_fusion import WORDS_COLUMN

    rungs = np.atleast_2d(np.asarray(ladder, np.float64))
    root = np.sqrt(np.maximum(rungs, 0.0))
    if n <= 0 or not len(rungs):
        return np.zeros(0, np.int64)
    cache = open_column(db, WORDS_COLUMN)
    if cache is None:  # no cache to stream from (a read-only store): its rows at once
        ids, rows = stored_words(db, allowed)
    else:
        ids = cache.ids if allowed is None else np.intersect1d(cache.ids, allowed)
        best_ids = best_rows(
            cache, ids, max(_SHORTLIST * n, n),
            lambda rows: (np.sqrt(np.maximum(rows, 0.0)) @ root.T).max(axis=1), block=BLOCK,
        )  # fmt: skip
        ids, rows = stored_words(db, best_ids)
    near = words_distances(rungs, rows)
    return np.asarray(ids[np.lexsort((ids, near))[:n]], np.int64)
