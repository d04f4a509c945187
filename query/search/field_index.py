"""The field vector index: the stored shapes nearest by the L1 of their scaled field vectors.

The light field stage (:mod:`query.search.rerank_lightfield`) re-ranks version 4's ``K``
nearest shapes, and with ``StageTuning.field_candidates = K2 > 0`` also the
``K2`` nearest by the L1 distance of the scaled field vectors ``[alpha * depth, gamma *
harmonic]`` (:meth:`query.search.field_fusion.FieldFusion.scaled`) not among those ``K``. This
module finds those ``K2``: something proposes candidates, and the exact float64 L1 of the
float32 scaled vectors orders them (ties by ascending id). Up to :data:`SCAN_MAX` live
vectors a float32 numpy scan proposes ``k + 16``; beyond, an approximate faiss
``IndexHNSWFlat(d, HNSW_M, METRIC_L1)`` proposes :data:`OVERSAMPLE` times as many (a
full scan of 10^6 x 950 floats costs about a second a query). A search restricted to
some ids (a ``where`` filter, an evaluation over the labelled shapes) scans them
exactly instead.

One index per store (:func:`field_index`), read from the store's ``field_vector``
column segment by segment (:mod:`query.search.field_rows`) and kept in
``<store>/index_field/`` (:mod:`query.search.versioned`; in memory only for a store the
process cannot write). It records the segment files it has read; at a new store version
it reads only the segments it has not (new shapes, shapes re-ingested under their id,
and the rewritten segments of a deletion), adds the rows that are new or changed and
tombstones the ids that are gone, instead of rebuilding. Below :data:`SCAN_MAX` it is
then compacted to its ascending-id order (what a fresh build gives); above, the HNSW
graph is rebuilt once more than a fifth of it is dead. Records without a field vector
are left out.
"""

from __future__ import annotations

import logging
import os
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from query.search import field_rows
from query.search.feature_index import faiss_knn_l1
from query.search.field_fusion import FieldFusion
from query.search.tuning import active
from query.search.versioned import POINTER, current, save_version
from shapedb.errors import StoreError

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = ["FieldIndex", "field_index", "forget", "SCAN_MAX", "OVERSAMPLE", "INDEX_DIR"]

log = logging.getLogger(__name__)

#: Where the index is kept beside its store.
INDEX_DIR = "index_field"
#: Extra proposals asked past k, so that float32 rounding cannot push a neighbour out
#: before the exact float64 order.
_MARGIN = 16
#: Up to this many vectors an exact float32 scan proposes the candidates; beyond, the
#: HNSW graph.
SCAN_MAX = 65_536
#: HNSW proposals per wanted candidate (k + 16), efSearch the same: recall@200 0.998 at 10^5
#: clustered 950-d vectors (0.994 at 1, 0.999 at 4; bench.studies.field_index_recall).
OVERSAMPLE = 2
#: HNSW graph degree and build beam: efConstruction 160 built 10^5 x 950 in 433 s on 2 busy
#: cores (80: 180 s, recall@200 0.98; bench.studies.field_index_recall).
HNSW_M = 32
EF_CONSTRUCTION = 160
#: A graph more than this fraction dead is rebuilt from its live vectors (as FeatureIndex).
_REBUILD_DEAD_FRACTION = 0.2
#: An update is written to disk once the changes since the saved index pass this fraction
#: of it (a policy: below it a new process re-reads those few segments at its first search).
_RESAVE_FRACTION = 0.02
_SCAN_BLOCK = 4096
_ADD_BLOCK = 65_536
_FORMAT = 1


def _faiss() -> Any:
    from shapedb.errors import require

    return require("faiss", extra="faiss", feature="the field vector index")


class FieldIndex:
    """Nearest neighbours by the L1 distance of scaled field vectors.

    Parameters
    ----------
    ids : (n,) int
        Shape ids, unique.
    vectors : (n, d) float
        Their scaled field vectors (:meth:`FieldFusion.scaled`), finite.

    Attributes
    ----------
    ids_ : (n,) int64
        Shape id of each position (ascending after construction; appended after).
    alive_ : (n,) bool
        False for tombstoned positions (removed or superseded ids).
    segments_ : tuple of str
        The store segment files the index reflects (:func:`field_index`).
    version_ : int or None
        The store version it was brought up to.
    """

    def __init__(self, ids: ArrayLike, vectors: ArrayLike) -> None:
        ids_a = np.asarray(ids, np.int64).ravel()
        vectors_a = np.asarray(vectors, np.float32)
        if np.any(ids_a[1:] <= ids_a[:-1]):  # a fresh read of a store is in order already
            order = np.argsort(ids_a, kind="stable")
            ids_a, vectors_a = ids_a[order], vectors_a[order]
        self.ids_ = ids_a
        self._vectors: NDArray[np.float32] | None = np.ascontiguousarray(vectors_a)
        if len(np.unique(self.ids_)) != len(self.ids_):
            raise ValueError("field index: ids must be unique")
        self.alive_ = np.ones(len(ids_a), bool)
        self.dim = int(self._vectors.shape[1]) if self._vectors.ndim == 2 else 0
        self._graph: Any = None
        self._keys: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None
        self._build_lock = threading.Lock()
        self.segments_: tuple[str, ...] = ()
        self.version_: int | None = None
        self.scales_: list[Any] | None = None
        self.unsaved_ = len(ids_a)  # changes, and rows read, since the index was saved

    def __len__(self) -> int:
        return int(self.alive_.sum())

    @property
    def vectors_(self) -> NDArray[np.float32]:
        """(n, d) float32 vectors by position: the graph's own storage once it is built
        (a view, valid while the graph is unchanged), so they are held once."""
        if self._graph is None:
            assert self._vectors is not None
            return self._vectors
        n = int(self._graph.ntotal)
        if n == 0:
            return np.zeros((0, self.dim), np.float32)
        storage = _faiss().downcast_index(self._graph.storage)
        return _faiss().rev_swig_ptr(storage.get_xb(), n * self.dim).reshape(n, self.dim)

    @property
    def approximate(self) -> bool:
        """Whether the HNSW graph proposes (more than :data:`SCAN_MAX` live vectors)."""
        return len(self) > SCAN_MAX

    def _index(self) -> Any:
        """The HNSW graph over every position, built at first need."""
        with self._build_lock:
            if self._graph is None:  # built aside: a search meanwhile reads the vectors
                graph, vectors = _new_graph(self.dim), self.vectors_
                for lo in range(0, len(vectors), _ADD_BLOCK):
                    graph.add(np.ascontiguousarray(vectors[lo : lo + _ADD_BLOCK]))
                self._graph, self._vectors = graph, None
                log.info("field vector HNSW graph of %d vectors built", graph.ntotal)
        return self._graph

    def lookup(self, ids: ArrayLike) -> NDArray[np.int64]:
        """Position of each id, -1 for ids not (or no longer) indexed: (m,) int64."""
        if self._keys is None:
            live = np.flatnonzero(self.alive_)
            order = np.argsort(self.ids_[live], kind="stable")
            self._keys = (self.ids_[live][order], live[order])
        keys, pos = self._keys
        q = np.asarray(ids, np.int64).ravel()
        if not len(keys):
            return np.full(len(q), -1, np.int64)
        at = np.minimum(np.searchsorted(keys, q), len(keys) - 1)
        return np.where(keys[at] == q, pos[at], -1)

    def search(
        self, queries: ArrayLike, k: int, *, allowed: ArrayLike | None = None
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """The ``k`` nearest indexed shapes of each scaled query vector.

        Parameters
        ----------
        queries : (q, d) float
            Scaled field vectors; a row with NaN gets no neighbour.
        k : int
            Neighbours wanted, >= 1.
        allowed : (m,) int, optional
            Restrict the results to these ids (an exact scan of them).

        Returns
        -------
        ids : (q, k) int64
            Nearest first, ties by ascending id; -1 pads. Above :data:`SCAN_MAX` live
            vectors the candidates are the graph's proposals (approximate).
        distances : (q, k) float64
            L1 distances (float64 over the float32 vectors); inf pads.
        """
        q = np.atleast_2d(np.asarray(queries, np.float64))
        k = int(k)
        out_i = np.full((len(q), k), -1, np.int64)
        out_d = np.full((len(q), k), np.inf)
        ok = np.all(np.isfinite(q), axis=1)
        n_live = len(self)
        if not n_live or not ok.any() or k < 1:
            return out_i, out_d
        if allowed is not None:
            wanted = np.isin(self.ids_, np.asarray(allowed, np.int64)) & self.alive_
            cand = np.flatnonzero(wanted)
            for row in np.flatnonzero(ok):
                out_i[row], out_d[row] = self._exact(q[row], cand, k)
            return out_i, out_d
        rows = np.flatnonzero(ok)
        q32 = np.ascontiguousarray(q[rows], np.float32)
        found = self.propose(q32, k) if self.approximate else self._scan(q32, k)
        for at, row in enumerate(rows):
            cand = found[at][found[at] >= 0]
            out_i[row], out_d[row] = self._exact(q[row], cand, k)
        return out_i, out_d

    def _scan(self, q32: NDArray[np.float32], k: int) -> NDArray[np.int64]:
        """(q, k + 16) positions of the nearest live vectors by an exact float32 L1 scan
        (faiss's brute-force search over the vectors in place, one thread for a few queries:
        14x numpy's at 10^4 x 950, 1.2 against 17.6 ms)."""
        n_cand = min(k + _MARGIN, len(self))
        n_dead = int(len(self.ids_) - len(self))
        ask = min(n_cand + n_dead, len(self.ids_))
        found = np.asarray(faiss_knn_l1(q32, np.asarray(self.vectors_, np.float32), ask), np.int64)
        if not n_dead:
            return found
        out = np.full((len(q32), n_cand), -1, np.int64)
        for at in range(len(q32)):
            live = found[at][(found[at] >= 0) & self.alive_[np.maximum(found[at], 0)]]
            out[at, : min(n_cand, len(live))] = live[:n_cand]
        return out

    def propose(self, q32: NDArray[np.float32], k: int) -> NDArray[np.int64]:
        """(q, c) positions the HNSW graph proposes for ``k`` neighbours of the float32
        queries (q, d): ``c = OVERSAMPLE * (k + 16)``, more when some are dead; -1 for
        none or dead. Builds the graph at its first call."""
        faiss = _faiss()
        graph = self._index()
        n_total, n_live = len(self.ids_), len(self)
        n_prop = OVERSAMPLE * (k + _MARGIN)
        n_prop = min(int(np.ceil(n_prop * n_total / n_live)), n_total)
        params = faiss.SearchParametersHNSW(efSearch=n_prop)
        found = np.asarray(graph.search(q32, n_prop, params=params)[1], np.int64)
        valid = found >= 0
        valid[valid] = self.alive_[found[valid]]
        return np.where(valid, found, -1)

    def _exact(
        self, query: NDArray[np.float64], positions: NDArray[Any], k: int
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """(k,) ids and distances of the nearest of ``positions``, exact, ties by id."""
        out_i = np.full(k, -1, np.int64)
        out_d = np.full(k, np.inf)
        best_i = np.empty(0, np.int64)
        best_d = np.empty(0)
        positions = np.asarray(positions, np.int64)
        vectors = self.vectors_
        for lo in range(0, len(positions), _SCAN_BLOCK):
            p = positions[lo : lo + _SCAN_BLOCK]
            d = np.abs(vectors[p].astype(np.float64) - query).sum(axis=1)
            all_i = np.concatenate([best_i, self.ids_[p]])
            all_d = np.concatenate([best_d, d])
            order = np.lexsort((all_i, all_d))[:k]
            best_i, best_d = all_i[order], all_d[order]
        out_i[: len(best_i)], out_d[: len(best_d)] = best_i, best_d
        return out_i, out_d

    # ---------------------------------------------------------------- changes
    def copy(self) -> FieldIndex:
        """An independent copy (graph cloned, ``alive_`` copied; the other arrays are only
        ever replaced, so they are shared): searches in flight keep the original."""
        other = FieldIndex.__new__(FieldIndex)
        other.__dict__.update(self.__dict__)
        other.alive_ = self.alive_.copy()
        other._build_lock = threading.Lock()
        if self._graph is not None:
            other._graph = _faiss().clone_index(self._graph)
        return other

    def remove(self, ids: ArrayLike) -> int:
        """Tombstone ``ids`` (those indexed); returns how many were."""
        pos = self.lookup(ids)
        pos = pos[pos >= 0]
        self.alive_[pos] = False
        self._keys = None
        self.unsaved_ += len(pos)
        return len(pos)

    def add(self, ids: ArrayLike, vectors: ArrayLike) -> None:
        """Append the vectors of ids not indexed (the caller removes an id's old vector first)."""
        ids_a = np.asarray(ids, np.int64).ravel()
        vectors_a = np.ascontiguousarray(np.asarray(vectors, np.float32).reshape(-1, self.dim))
        if not len(ids_a):
            return
        if len(np.unique(ids_a)) != len(ids_a):
            raise ValueError("field index: ids must be unique")
        if self._graph is not None:
            self._graph.add(vectors_a)
        else:
            self._vectors = np.concatenate([self.vectors_, vectors_a])
        self.ids_ = np.concatenate([self.ids_, ids_a])
        self.alive_ = np.concatenate([self.alive_, np.ones(len(ids_a), bool)])
        self._keys = None
        self.unsaved_ += len(ids_a)

    def settle(self) -> None:
        """Below :data:`SCAN_MAX`: compact to the live positions in ascending id order (as a
        fresh build); above: build the graph, rebuilt once a fifth of it is dead."""
        live = np.flatnonzero(self.alive_)
        if not self.approximate:
            in_order = not np.any(self.ids_[1:] <= self.ids_[:-1])
            if self._graph is None and len(live) == len(self.ids_) and in_order:
                return
            keep = live[np.argsort(self.ids_[live], kind="stable")]
            self._vectors = np.ascontiguousarray(self.vectors_[keep])
            self.ids_, self.alive_, self._graph = self.ids_[keep], self.alive_[keep], None
        elif 1 - len(live) / len(self.ids_) > _REBUILD_DEAD_FRACTION:
            graph, old = _new_graph(self.dim), self.vectors_
            for lo in range(0, len(live), _ADD_BLOCK):
                graph.add(np.ascontiguousarray(old[live[lo : lo + _ADD_BLOCK]]))
            self.ids_, self.alive_, self._graph = self.ids_[live], self.alive_[live], graph
            self._vectors = None
        self._keys = None
        if self.approximate:
            self._index()

    # ---------------------------------------------------------------- disk
    def save(self, directory: str | os.PathLike[str], *, version: int | None = None) -> Path:
        """Write the index atomically under ``directory`` (:func:`save_version`)."""

        def write(sub: Path) -> None:
            np.save(sub / "ids.npy", self.ids_)
            np.save(sub / "alive.npy", self.alive_)
            if self._graph is not None:
                _faiss().write_index(self._graph, str(sub / "graph.faiss"))
            else:
                np.save(sub / "vectors.npy", self.vectors_)

        meta = {
            "format": _FORMAT,
            "version": version,
            "n": len(self.ids_),
            "dim": self.dim,
            "scales": self.scales_,
            "segments": list(self.segments_),
        }
        path = save_version(directory, write, meta, version=version)
        self.unsaved_ = 0
        return path

    @classmethod
    def load(cls, directory: str | os.PathLike[str]) -> FieldIndex:
        """Read the index ``<directory>/current.json`` points to (StoreError when damaged)."""
        root = Path(directory)
        meta, sub = _pointer(root)
        try:
            ids, alive = np.load(sub / "ids.npy"), np.load(sub / "alive.npy")
            index = cls(np.empty(0, np.int64), np.zeros((0, int(meta["dim"])), np.float32))
            if (sub / "graph.faiss").exists():
                index._graph, index._vectors = _faiss().read_index(str(sub / "graph.faiss")), None
                n_vectors = int(index._graph.ntotal)
            else:
                index._vectors = np.load(sub / "vectors.npy")
                n_vectors = len(index._vectors)
        except (OSError, ValueError, KeyError, RuntimeError) as exc:
            raise StoreError(f"cannot read the field vector index: {exc}", source=root) from exc
        if not (len(ids) == len(alive) == n_vectors == int(meta["n"])):
            raise StoreError("field index files disagree on the number of vectors", source=root)
        index.ids_, index.alive_, index.unsaved_ = ids, alive, 0
        index.segments_, index.version_ = tuple(meta["segments"]), meta["version"]
        index.scales_ = meta["scales"]
        return index


def _pointer(root: Path) -> tuple[dict[str, Any], Path]:
    """The saved index's metadata and directory (StoreError when unreadable or foreign)."""
    try:
        meta, sub = current(root)
    except (OSError, ValueError, KeyError) as exc:
        raise StoreError(f"cannot read the field vector index: {exc}", source=root) from exc
    if meta.get("format") != _FORMAT:
        raise StoreError(f"unknown field index format {meta.get('format')!r}", source=root)
    return meta, sub


def _new_graph(dim: int) -> Any:
    faiss = _faiss()
    graph = faiss.IndexHNSWFlat(dim, HNSW_M, faiss.METRIC_L1)
    graph.hnsw.efConstruction = EF_CONSTRUCTION
    return graph


# ------------------------------------------------------------------ store glue
#: Field indexes by (store path, store version): the most recent few.
_INDEXES: dict[tuple[str, int], tuple[Any, FieldIndex]] = {}
_KEEP = 4
_LOCK = threading.Lock()  # the table above
_UPDATE = threading.Lock()  # one build or update at a time


def field_index(db: StoreHandle) -> FieldIndex:
    """The shared :class:`FieldIndex` of ``db``'s store at its current version.

    Over the ``field_vector`` column, scaled by ``db.config``'s fusion under the active
    stage numbers (:func:`query.search.tuning.active`, :meth:`FieldFusion.scaled`): the
    one of an earlier version (in this process, or saved in ``<store>/index_field/``)
    brought up to date, else built; rebuilt when the fusion weights change. A store without field vectors gets an empty index.
    """
    fusion = FieldFusion.from_config(db.config, active())
    path = os.fspath(db.store.path)
    key = (path, int(db.store.version))
    scales = _scales(fusion)
    with _LOCK:
        cached = _INDEXES.get(key)
    if cached is not None and cached[0] == scales:
        return cached[1]
    with _UPDATE:
        with _LOCK:
            cached = _INDEXES.get(key)
            earlier = [v for k, v in sorted(_INDEXES.items()) if k[0] == path and v[0] == scales]
        if cached is not None and cached[0] == scales:
            return cached[1]
        if not fusion.stored:
            index = FieldIndex(np.empty(0, np.int64), np.zeros((0, _dim(db, fusion)), np.float32))
        else:
            base = earlier[-1][1] if earlier else _load(Path(path) / INDEX_DIR, scales)
            index = field_rows.consistent(db, lambda snap: _up_to_date(base, snap, fusion, db))
        with _LOCK:
            _INDEXES[key] = (scales, index)
            while len(_INDEXES) > _KEEP:
                _INDEXES.pop(next(iter(_INDEXES)))
    return index


def _up_to_date(
    base: FieldIndex | None, snap: field_rows.Snapshot, fusion: FieldFusion, db: StoreHandle
) -> FieldIndex:
    """``base`` brought to ``snap`` (a copy when anything changed), or a fresh build."""
    from query.search.index import keep_beside

    dim = _stored_dim(db)
    if base is not None and base.segments_ == snap.files:
        return base
    if base is None:
        index, action = _build(snap, fusion, dim), "built"
    else:
        index, action = base.copy(), "updated"
        _sync(index, snap, fusion, dim)
    index.settle()
    index.segments_, index.version_, index.scales_ = snap.files, snap.version, _scales(fusion)
    log.info(
        "field vector index %s at store version %d: %d shapes", action, snap.version, len(index)
    )
    if index.unsaved_ > _RESAVE_FRACTION * len(index.ids_):
        keep_beside(index, snap.root / INDEX_DIR, snap.version, "field vector index")
    return index


def _build(snap: field_rows.Snapshot, fusion: FieldFusion, dim: int) -> FieldIndex:
    """A fresh index of the snapshot's rows; a large one streams into its graph."""
    width = fusion.scaled(np.zeros((1, dim))).shape[1]
    empty = FieldIndex(np.empty(0, np.int64), np.zeros((0, width), np.float32))
    if snap.rows > SCAN_MAX:
        empty._index()  # an empty graph: each batch goes straight into it
        for _, ids, vectors in field_rows.read_rows(snap, fusion, dim):
            empty.add(ids, vectors)
        return empty
    out_i = np.empty(snap.rows, np.int64)
    out_v = np.empty((snap.rows, width), np.float32)
    n = 0
    for _, ids, vectors in field_rows.read_rows(snap, fusion, dim):
        out_i[n : n + len(ids)], out_v[n : n + len(ids)] = ids, vectors
        n += len(ids)
    return FieldIndex(out_i[:n], out_v[:n])


def _sync(index: FieldIndex, snap: field_rows.Snapshot, fusion: FieldFusion, dim: int) -> None:
    """Read the segments ``index`` has not; add new or changed rows, tombstone the gone.

    Their rows are new shapes, copies of kept ones (a deletion rewrites its segment), or
    shapes stored again under their id; the changes are applied every
    :data:`_ADD_BLOCK` rows, so the id lookup is not rebuilt at every batch.
    """
    unread = snap.only(set(snap.files) - set(index.segments_))
    index.remove(np.setdiff1d(index.ids_[index.alive_], field_rows.read_ids(snap)))
    gone: list[NDArray[np.int64]] = []
    new: list[tuple[NDArray[np.int64], NDArray[np.float32]]] = []
    for rows, ids, vectors in field_rows.read_rows(unread, fusion, dim):
        pos = index.lookup(rows)
        has = np.isin(rows, ids)  # ids are the rows with a field vector, in order
        gone.append(rows[(pos >= 0) & ~has])  # stored again without one
        pos = pos[has]
        same = pos >= 0
        same[same] = np.all(index.vectors_[pos[same]] == vectors[same], axis=1)
        gone.append(ids[(pos >= 0) & ~same])  # stored again with another one
        new.append((ids[~same], vectors[~same]))
        index.unsaved_ += len(rows)
        if sum(len(i) for i, _ in new) >= _ADD_BLOCK:
            _apply(index, gone, new)
    _apply(index, gone, new)


def _apply(
    index: FieldIndex,
    gone: list[NDArray[np.int64]],
    new: list[tuple[NDArray[np.int64], NDArray[np.float32]]],
) -> None:
    """Tombstone ``gone``, then add ``new``; empties both lists."""
    if gone:
        index.remove(np.concatenate(gone))
    if new:
        index.add(np.concatenate([i for i, _ in new]), np.concatenate([v for _, v in new]))
    gone.clear()
    new.clear()


def _load(directory: Path, scales: list[Any]) -> FieldIndex | None:
    if not (directory / POINTER).exists():
        return None
    try:
        index = FieldIndex.load(directory)
    except StoreError as exc:
        log.warning("rebuilding the field vector index: %s", exc)
        return None
    if index.scales_ != scales:
        return None
    index.settle()  # as this process's SCAN_MAX has it
    return index


def _scales(fusion: FieldFusion) -> list[Any]:
    """What the scaled vectors depend on, JSON-serialisable."""
    d, h = fusion.depth, fusion.harmonic
    return [fusion.alpha, fusion.gamma, [d.start, d.stop], [h.start, h.stop]]


def _stored_dim(db: StoreHandle) -> int:
    from shapedb.signature.field_vector import field_vector_dim

    return int(field_vector_dim(db.config.field_vector))


def _dim(db: StoreHandle, fusion: FieldFusion) -> int:
    """Length of a scaled vector (0 for a store without field vectors)."""
    return 0 if not fusion.stored else int(fusion.scaled(np.zeros((1, _stored_dim(db)))).shape[1])


def forget(path: str) -> None:
    """Drop the in-process indexes of the store at ``path`` (tests: as a new process would)."""
    with _LOCK:
        for key in [k for k in _INDEXES if k[0] == path]:
            _INDEXES.pop(key, None)
