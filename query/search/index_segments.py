"""The feature index kept in step with its store segment by segment.

A :class:`query.search.feature_index.FeatureIndex` opened on a store
(:func:`query.search.index.open_index`) records the ``shapes`` segment files it reflects
(``segments_``) and the segment each of its positions was read from (``segs_``). Segment
files are immutable, so at a new store version :func:`catch_up` reads only the segments it has not read, through
:mod:`query.search.field_rows`:

- a segment a deletion or compaction wrote copies rows of the segments it retires (its
  ``shapedb.replaces``, :func:`query.search.field_rows.copied_from`): when the index holds
  every one of those rows, only the segment's ids are read and the rows re-pointed;
- any other segment's rows are read whole: ids not indexed are added, ids indexed with
  the same vector re-pointed, ids indexed with another vector (a shape stored again
  under its id) tombstoned and added again;
- the ids left in a segment the store no longer lists are tombstoned.

Reading the unread segments costs O(the commit), not O(the store). The row of a shape is
its ``feature``, or for the sparse-view index its ``view_feature`` where it has one
(:meth:`shapedb.store.store.Store.features`). A snapshot is read completely before the
index is changed, so a reader that finds a segment gone (FileNotFoundError) may start
again from a fresh manifest (:func:`query.search.field_rows.consistent`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from query.search import field_rows
from shapedb.errors import StoreError

if TYPE_CHECKING:
    from query.search.feature_index import FeatureIndex

__all__ = ["read_features", "build", "catch_up"]

#: Rows read from the store: (ids, features, index into the snapshot's files of each segment).
Rows = tuple[NDArray[np.int64], NDArray[np.float32], NDArray[np.int32]]


def read_features(snap: field_rows.Snapshot, *, view: bool) -> Rows:
    """Every row of the snapshot's segments, in the manifest's order.

    Returns
    -------
    ids : (n,) int64
    features : (n, d) float32
        Each shape's ``feature`` (``view``: its ``view_feature`` where set); d = ``snap.dim``.
    segment : (n,) int32
        The index into ``snap.files`` of each row's segment.

    Raises
    ------
    StoreError
        A segment is damaged, or holds other rows than the manifest says.
    """
    d, total = snap.dim, snap.rows
    ids = np.empty(total, np.int64)
    feats = np.empty((total, d), np.float32)
    n = 0
    columns = ["id", "feature", "view_feature"] if view else ["id", "feature"]
    for batch in field_rows.batches(snap, columns):
        m = batch.num_rows
        valid, rows = field_rows.list_rows(batch.column(1), d, snap.root)
        if n + m > total or not valid.all():
            raise StoreError("segments disagree with the manifest", source=str(snap.root))
        ids[n : n + m] = batch.column(0).to_numpy()
        feats[n : n + m] = rows
        if view:
            has, views = field_rows.list_rows(batch.column(2), d, snap.root)
            feats[n : n + m][has] = views
        n += m
    if n != total:
        raise StoreError(f"segments of {n} rows, the manifest says {total}", source=str(snap.root))
    counts = [int(s.get("rows", 0)) for s in snap.segments]
    return ids, feats, np.repeat(np.arange(len(counts), dtype=np.int32), counts)


def build(
    index: FeatureIndex, snap: field_rows.Snapshot, weights: ArrayLike, *, view: bool
) -> FeatureIndex:
    """Fit the unfitted ``index`` to every row of the snapshot, in ascending id order (as
    :meth:`FeatureIndex.fit` on :meth:`Store.features`)."""
    ids, feats, segs = read_features(snap, view=view)
    if np.any(ids[1:] <= ids[:-1]):
        order = np.argsort(ids, kind="stable")
        ids, feats, segs = ids[order], feats[order], segs[order]
    index.fit(ids, feats, weights)
    index.segs_, index.segments_ = segs, snap.files
    return index


def catch_up(index: FeatureIndex, snap: field_rows.Snapshot, *, view: bool) -> int:
    """Bring ``index`` (fitted, with ``segments_``) to the snapshot by reading only the
    segments it has not read (see the module docstring); returns the rows read.

    Everything is read before ``index`` changes: a FileNotFoundError leaves it as it was.
    Call :meth:`FeatureIndex.settle` afterwards to apply the rebuild rules.
    """
    where = {f: j for j, f in enumerate(snap.files)}
    copies, fresh = _copied_rows(index, snap)
    unread = snap.only(set(fresh))
    ids, feats, sub = read_features(unread, view=view)
    seg = np.asarray([where[f] for f in unread.files], np.int32)[sub]
    # the read is done: from here on the index changes
    remap = np.asarray([where.get(f, -1) for f in index.segments_] + [-1], np.int32)
    segs = remap[index.segs_]  # -1: a segment the store no longer lists (or unknown)
    for j, pos in copies:
        segs[pos] = j
    pos = index.lookup(ids)
    has = pos >= 0
    same = has.copy()
    same[has] = np.all(np.asarray(index.features_[pos[has]]) == feats[has], axis=1)
    segs[pos[same]] = seg[same]
    gone = index.alive_ & (segs < 0)
    gone[pos[has & ~same]] = True  # stored again under its id with another vector
    index.segs_, index.segments_ = segs, snap.files
    index.remove(index.ids_[gone])
    add = np.flatnonzero(~same)
    add = add[np.argsort(ids[add], kind="stable")]
    index.add(ids[add], feats[add], segments=seg[add])
    n_copied = sum(len(p) for _, p in copies)
    index.unsaved_ += n_copied + int(same.sum())
    return n_copied + len(ids)


def _copied_rows(
    index: FeatureIndex, snap: field_rows.Snapshot
) -> tuple[list[tuple[int, NDArray[np.int64]]], list[str]]:
    """The unread segments split: ``(j, positions)`` of those that only copy rows the index
    holds (from segments the store no longer lists), and the files of the others."""
    known = {f: i for i, f in enumerate(index.segments_)}
    retired = set(index.segments_) - set(snap.files)
    copies: list[tuple[int, NDArray[np.int64]]] = []
    fresh: list[str] = []
    for j, f in enumerate(snap.files):
        if f in known:
            continue
        sources = field_rows.copied_from(snap, f)
        if sources and all(s in retired for s in sources):
            pos = index.lookup(field_rows.read_ids(snap.only({f})))
            held = np.asarray([known[s] for s in sources], np.int32)
            if np.all(pos >= 0) and np.all(np.isin(index.segs_[pos], held)):
                copies.append((j, pos))
                continue
        fresh.append(f)
    return copies, fresh
