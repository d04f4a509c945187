"""The faiss index over Eq. 1 feature vectors: :class:`FeatureIndex`.

Eq. 2 is a weighted L1 distance, ``d(a, b) = sum_i w_i |a_i - b_i|`` with
``w = weights(config)``, which is the plain L1 distance between ``a * w`` and
``b * w``. The index therefore holds the *weighted* vectors under faiss's
``METRIC_L1``:

``kind="flat"`` is ``IndexFlat(d, METRIC_L1)`` (exact), ``kind="hnsw"`` is
``IndexHNSWFlat(d, M, METRIC_L1)`` (approximate) and ``kind="auto"`` picks flat
below ``hnsw_threshold`` vectors, HNSW above.

Either way faiss only proposes candidates (``max(oversample * k, min_candidates)``
of them); they are re-ranked with the exact Eq. 2 in float64 on the raw stored
features, ties broken by ascending id. faiss positions are mapped to shape ids with
a side array (``ids_``). Removed ids are tombstoned (``alive_``), and
:meth:`FeatureIndex.settle` rebuilds from the live vectors when the rules say so.

Saved (:meth:`FeatureIndex.save`) as a versioned directory (:mod:`query.search.versioned`)
of ``faiss.index``, ``ids.npy``, ``features.npy``, ``alive.npy`` and ``segs.npy``; the
store's own index is kept in step by :mod:`query.search.index`. faiss is imported only
when an index is built or loaded.
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from query.search.versioned import current, save_version
from shapedb.errors import ConfigError, NotFittedError, QueryError, StoreError, require

__all__ = ["FeatureIndex", "faiss_knn_l1"]

log = logging.getLogger(__name__)

_FORMAT = 1
_KINDS = ("auto", "flat", "hnsw")
_PARAMS = tuple(
    "kind hnsw_threshold hnsw_m ef_construction ef_search oversample min_candidates".split()
)
_REBUILD_DEAD_FRACTION = 0.2
#: Spare rows kept after ``features_`` (as a fraction of it), so that a commit's rows are
#: written in place rather than the whole matrix copied: a copy every 1/8 growth.
_SPARE_ROWS = 0.125
_ADD_BLOCK = 65_536
_RERANK_CHUNK = 256
_SCAN_BLOCK = 65_536
_SMALL_BATCH = 4


class FeatureIndex:
    """Nearest neighbours under the Eq. 2 weighted L1 distance.

    Parameters
    ----------
    kind : {"auto", "flat", "hnsw"}
        Index type; ``"auto"`` picks flat below ``hnsw_threshold`` vectors.
    hnsw_threshold : int
        Size from which ``"auto"`` uses HNSW.
    hnsw_m : int
        HNSW graph degree M.
    ef_construction : int
        HNSW build-time beam width.
    ef_search : int
        HNSW search beam width (raised to the number of candidates if smaller).
    oversample : int
        Candidates asked from faiss per result, before exact re-ranking.
    min_candidates : int
        Lower bound on the number of candidates.

    Attributes
    ----------
    ids_ : (n,) int64
        Shape id of each faiss position.
    features_ : (n, d) float32
        Raw (unweighted) feature vector of each position, used for re-ranking.
    alive_ : (n,) bool
        False for positions whose shape was deleted (tombstones).
    weights_ : (d,) float64
        Eq. 2 weights the index was built with.
    kind_ : str
        The index type actually built, "flat" or "hnsw".
    version_ : int or None
        Store version the index reflects (set by :func:`open_index`).
    segments_ : tuple of str
        The store segment files it reflects (() when not opened on a store).
    segs_ : (n,) int32
        Index into ``segments_`` of the segment each position was read from (-1: none).
    unsaved_ : int
        Rows changed or read since the index was last saved.
    """

    def __init__(
        self,
        *,
        kind: str = "auto",
        hnsw_threshold: int = 50_000,
        hnsw_m: int = 32,
        ef_construction: int = 80,
        ef_search: int = 128,
        oversample: int = 4,
        min_candidates: int = 64,
    ) -> None:
        if kind not in _KINDS:
            raise ConfigError(f"must be one of {_KINDS}", source=f"kind={kind!r}")
        self.kind = kind
        self.hnsw_threshold = hnsw_threshold
        self.hnsw_m = hnsw_m
        self.ef_construction = ef_construction
        self.ef_search = ef_search
        self.oversample = oversample
        self.min_candidates = min_candidates
        self.version_: int | None = None

    @property
    def params(self) -> dict[str, Any]:
        """The constructor's settings, as a JSON-serialisable dict."""
        return {name: getattr(self, name) for name in _PARAMS}

    def _check_fitted(self) -> None:
        if not hasattr(self, "faiss_index_"):
            raise NotFittedError("FeatureIndex used before fit()", source="FeatureIndex")

    @property
    def dim(self) -> int:
        """Feature dimension d."""
        self._check_fitted()
        return int(self.weights_.shape[0])

    @property
    def n_alive(self) -> int:
        """Number of live (not deleted) vectors."""
        self._check_fitted()
        return int(self.alive_.sum())

    def _resolve_kind(self, n: int) -> str:
        if self.kind != "auto":
            return self.kind
        return "hnsw" if n >= self.hnsw_threshold else "flat"

    def _weighted(self, features: NDArray[Any]) -> NDArray[np.float32]:
        return np.ascontiguousarray(np.asarray(features, np.float64) * self.weights_, np.float32)

    def fit(self, ids: ArrayLike, features: ArrayLike, weights: ArrayLike) -> FeatureIndex:
        """Build the index from scratch.

        Parameters
        ----------
        ids : (n,) int
            Shape ids, unique.
        features : (n, d) float
            Raw Eq. 1 feature vectors.
        weights : (d,) float
            Eq. 2 weights, ``shapedb.signature.kernel.weights(config)``.

        Returns
        -------
        FeatureIndex
            ``self``.
        """
        w = np.asarray(weights, dtype=np.float64).ravel()
        ids_a, feats = _check_rows(ids, features, w.shape[0])
        self.weights_ = w
        self.kind_ = self._resolve_kind(len(ids_a))
        faiss = _faiss()
        if self.kind_ == "flat":
            self.faiss_index_ = faiss.IndexFlat(w.shape[0], faiss.METRIC_L1)
        else:
            self.faiss_index_ = faiss.IndexHNSWFlat(w.shape[0], self.hnsw_m, faiss.METRIC_L1)
            self.faiss_index_.hnsw.efConstruction = self.ef_construction
        self.ids_ = np.empty(0, np.int64)
        self.features_ = np.empty((0, w.shape[0]), np.float32)
        self._room: list[Any] | None = None
        self.alive_ = np.empty(0, bool)
        self.segs_ = np.empty(0, np.int32)
        self.segments_: tuple[str, ...] = ()
        self._pos: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None
        self.unsaved_ = 0
        self._append(ids_a, feats)
        log.info("built %s index of %d vectors (d=%d)", self.kind_, len(ids_a), w.shape[0])
        return self

    def _append(
        self,
        ids: NDArray[np.int64],
        features: NDArray[np.float32],
        segs: NDArray[np.int32] | None = None,
    ) -> None:
        for lo in range(0, len(ids), _ADD_BLOCK):
            self.faiss_index_.add(self._weighted(features[lo : lo + _ADD_BLOCK]))
        self.ids_ = np.concatenate([self.ids_, ids])
        self.features_ = self._grown(features)
        self.alive_ = np.concatenate([self.alive_, np.ones(len(ids), bool)])
        more = np.full(len(ids), -1, np.int32) if segs is None else np.asarray(segs, np.int32)
        self.segs_ = np.concatenate([self.segs_, more])
        self._pos = None
        self.unsaved_ += len(ids)

    def _grown(self, rows: NDArray[np.float32]) -> NDArray[np.float32]:
        """``features_`` with ``rows`` after it: written into the spare rows of its buffer
        when this index was the last to fill it (copies made by :meth:`copy` share the
        buffer and see only their own rows), else copied into a new, larger buffer."""
        n, m = len(self.features_), len(rows)
        room = self._room  # [buffer, rows filled], shared with copies
        if room is not None and room[1] == n and n + m <= len(room[0]):
            if self.features_.base is room[0] or n == 0:
                room[0][n : n + m] = rows
                room[1] = n + m
                return room[0][: n + m]  # type: ignore[no-any-return]
        buffer = np.empty((n + m + int(_SPARE_ROWS * (n + m)) + 16, self.dim), np.float32)
        buffer[:n] = self.features_
        buffer[n : n + m] = rows
        self._room = [buffer, n + m]
        return buffer[: n + m]

    def add(
        self, ids: ArrayLike, features: ArrayLike, *, segments: ArrayLike | None = None
    ) -> FeatureIndex:
        """Append vectors of ids not indexed (tombstone an id's old vector first).

        Parameters
        ----------
        ids : (m,) int
        features : (m, d) float
            Raw Eq. 1 feature vectors.
        segments : (m,) int, optional
            Index into ``segments_`` of each one's store segment (-1 when not given).
        """
        self._check_fitted()
        ids_a, feats = _check_rows(ids, features, self.dim)
        if np.any(self.lookup(ids_a) >= 0):
            raise QueryError("ids already indexed", source="ids")
        segs = None if segments is None else np.asarray(segments, np.int32).ravel()
        self._append(ids_a, feats, segs)
        return self

    def remove(self, ids: ArrayLike) -> FeatureIndex:
        """Tombstone vectors by id; they are never returned again.

        Parameters
        ----------
        ids : (m,) int
        """
        pos = self.lookup(ids)
        pos = pos[pos >= 0]
        self.alive_[pos] = False
        self._pos = None
        self.unsaved_ += len(pos)
        return self

    def settle(self) -> str:
        """After :meth:`add` and :meth:`remove`: rebuild from the live vectors in ascending
        id order (what a fresh build gives) when the index is flat with tombstones or out
        of id order, HNSW more than a fifth dead, or ``"auto"`` and of the other size.

        Returns
        -------
        str
            "rebuilt" or "updated".
        """
        self._check_fitted()
        live = np.flatnonzero(self.alive_)
        ids = self.ids_[live]
        ordered = not np.any(ids[1:] <= ids[:-1])
        if not (
            self._resolve_kind(len(live)) != self.kind_
            or (self.kind_ == "flat" and (len(live) < len(self.ids_) or not ordered))
            or 1 - len(live) / max(len(self.ids_), 1) > _REBUILD_DEAD_FRACTION
        ):
            return "updated"
        keep = live[np.argsort(ids, kind="stable")]
        segs, segments = self.segs_[keep], self.segments_
        self.fit(self.ids_[keep], np.asarray(self.features_)[keep], self.weights_)
        self.segs_, self.segments_ = segs, segments
        return "rebuilt"

    def lookup(self, ids: ArrayLike) -> NDArray[np.int64]:
        """faiss position of each id, -1 for ids not (or no longer) indexed: (m,) int64."""
        self._check_fitted()
        if self._pos is None:
            live = np.flatnonzero(self.alive_)
            order = np.argsort(self.ids_[live], kind="stable")
            self._pos = (self.ids_[live][order], live[order])
        keys, pos = self._pos
        q = np.asarray(ids, dtype=np.int64).ravel()
        if len(keys) == 0:
            return np.full(len(q), -1, np.int64)
        i = np.minimum(np.searchsorted(keys, q), len(keys) - 1)
        return np.where(keys[i] == q, pos[i], -1)

    def __contains__(self, shape_id: object) -> bool:
        ok = isinstance(shape_id, (int, np.integer))
        return ok and bool(self.lookup([int(shape_id)])[0] >= 0)  # type: ignore[call-overload]

    def sync(self, ids: ArrayLike, features: ArrayLike) -> str:
        """Bring the index up to date with the store's current ``(ids, features)``.

        Existing vectors whose feature changed, or a flat index with deletions, or an
        HNSW index more than a fifth dead, or an ``"auto"`` index that outgrew its
        type, are rebuilt; otherwise new ids are added and deleted ones tombstoned.

        Returns
        -------
        str
            What was done: "unchanged", "updated" or "rebuilt".
        """
        self._check_fitted()
        ids_a, feats = _check_rows(ids, features, self.dim)
        found = self.lookup(ids_a)
        new_mask = found < 0
        old_pos = found[~new_mask]
        changed = not np.array_equal(np.asarray(self.features_)[old_pos], feats[~new_mask])
        n_live = self.n_alive
        n_deleted = n_live - len(old_pos)
        dead = len(self.ids_) - n_live + n_deleted
        dead_after = dead / max(len(self.ids_) + int(new_mask.sum()), 1)
        rebuild = (
            changed
            or self._resolve_kind(len(ids_a)) != self.kind_
            or (n_deleted and self.kind_ == "flat")
            or dead_after > _REBUILD_DEAD_FRACTION
        )
        if rebuild:
            self.fit(ids_a, feats, self.weights_)
            return "rebuilt"
        if not n_deleted and not new_mask.any():
            return "unchanged"
        if n_deleted:
            gone = np.ones(len(self.ids_), bool)
            gone[old_pos] = False
            self.alive_[gone] = False
            self._pos = None
        self._append(ids_a[new_mask], feats[new_mask])
        return "updated"

    def search(
        self, queries: ArrayLike, k: int = 10, *, allowed: ArrayLike | None = None
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """The k nearest stored vectors of each query under exact Eq. 2.

        Parameters
        ----------
        queries : (q, d) or (d,) float
            Raw Eq. 1 feature vectors.
        k : int
            Neighbours wanted.
        allowed : (m,) int, optional
            Restrict the results to these ids; the search is then exhaustive (exact).

        Returns
        -------
        ids : (q, k) int64
            Shape ids, nearest first (ties by ascending id); -1 pads rows when fewer
            than k vectors exist.
        distances : (q, k) float64
            Eq. 2 distances; inf where padded.
        """
        self._check_fitted()
        q = np.asarray(queries, dtype=np.float64)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != self.dim:
            raise QueryError(f"expected vectors of length {self.dim}", source=f"shape {q.shape}")
        if not np.all(np.isfinite(q)):
            raise QueryError("feature vector has NaN or inf entries", source="query")
        k = int(k)
        if k < 1:
            raise QueryError("k must be >= 1", source=f"k={k}")
        if allowed is not None:
            cand = np.unique(self.lookup(allowed))
            return self._scan(q, cand[cand >= 0], k)
        n_live = self.n_alive
        if n_live == 0:
            return np.full((len(q), k), -1, np.int64), np.full((len(q), k), np.inf)
        dead = len(self.ids_) - n_live
        n_cand = max(self.oversample * k, self.min_candidates, k)
        n_cand = int(np.ceil(n_cand * len(self.ids_) / n_live)) if dead else n_cand
        n_cand = min(n_cand, len(self.ids_))
        ef = max(self.ef_search, n_cand) if self.kind_ == "hnsw" else None
        cand = _faiss_search(self.faiss_index_, self._weighted(q), n_cand, ef_search=ef)
        return self._rerank(q, cand, k)

    def _rerank(
        self, q: NDArray[np.float64], cand: NDArray[np.int64], k: int
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Exact float64 Eq. 2 over per-query candidate positions (q, c); -1 = none."""
        out_ids = np.full((len(q), k), -1, np.int64)
        out_d = np.full((len(q), k), np.inf)
        feats = np.asarray(self.features_)
        for s in range(0, len(q), _RERANK_CHUNK):
            c = cand[s : s + _RERANK_CHUNK]
            valid = c >= 0
            valid[valid] = self.alive_[c[valid]]
            cc = np.where(valid, c, 0)
            x = feats[cc].astype(np.float64)  # (b, c, d): Eq. 2 in float64
            d = np.where(
                valid, np.abs(x - q[s : s + _RERANK_CHUNK, None, :]) @ self.weights_, np.inf
            )
            ids = np.where(valid, self.ids_[cc], np.iinfo(np.int64).max)
            order = np.lexsort((ids, d), axis=-1)[:, :k]
            top_d = np.take_along_axis(d, order, 1)
            top_i = np.take_along_axis(ids, order, 1)
            top_i[~np.isfinite(top_d)] = -1
            out_ids[s : s + len(c), : top_d.shape[1]] = top_i
            out_d[s : s + len(c), : top_d.shape[1]] = top_d
        return out_ids, out_d

    def _scan(
        self, q: NDArray[np.float64], positions: NDArray[np.int64], k: int
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Exhaustive exact Eq. 2 of every query against the same positions (m,)."""
        out_ids = np.full((len(q), k), -1, np.int64)
        out_d = np.full((len(q), k), np.inf)
        if len(positions) == 0:
            return out_ids, out_d
        ids = self.ids_[positions]
        for lo in range(0, len(positions), _SCAN_BLOCK):
            x = np.asarray(self.features_[positions[lo : lo + _SCAN_BLOCK]], np.float64)
            block_ids = ids[lo : lo + _SCAN_BLOCK]
            for j in range(len(q)):
                d = np.abs(x - q[j]) @ self.weights_
                # merge this block with the running best k, ties by ascending id
                all_d = np.concatenate([out_d[j], d])
                all_i = np.concatenate([out_ids[j], block_ids])
                if len(all_d) > 4 * k:
                    thr = np.partition(all_d, k - 1)[k - 1]
                    keep = all_d <= thr
                    all_d, all_i = all_d[keep], all_i[keep]
                key_i = np.where(all_i < 0, np.iinfo(np.int64).max, all_i)
                order = np.lexsort((key_i, all_d))[:k]
                out_d[j], out_ids[j] = all_d[order], all_i[order]
        out_ids[~np.isfinite(out_d)] = -1
        return out_ids, out_d

    def exact_search(
        self, queries: ArrayLike, k: int = 10
    ) -> tuple[NDArray[np.int64], NDArray[Any]]:
        """Brute-force exact search over every live vector (reference for recall)."""
        self._check_fitted()
        q = np.atleast_2d(np.asarray(queries, np.float64))
        return self._scan(q, np.flatnonzero(self.alive_), k)

    def copy(self) -> FeatureIndex:
        """An independent copy: faiss index cloned, ``alive_`` copied (the other
        arrays are only ever replaced, never modified in place, so they are shared)."""
        self._check_fitted()
        other = FeatureIndex(**self.params)
        other.__dict__.update(self.__dict__)
        other.faiss_index_ = _faiss().clone_index(self.faiss_index_)
        other.alive_ = self.alive_.copy()
        return other

    def features_of(self, shape_id: int) -> NDArray[np.float64] | None:
        """Stored feature vector of a shape id, or None when it is not indexed."""
        p = int(self.lookup([shape_id])[0])
        return None if p < 0 else np.asarray(self.features_[p], np.float64)

    def save(self, directory: str | os.PathLike[str], *, version: int | None = None) -> Path:
        """Write the index atomically under ``directory`` (an ``index/`` folder).

        A fresh sub-directory is written completely, then the pointer file
        ``current.json`` is replaced with :func:`os.replace`; older sub-directories
        are removed afterwards.
        """
        self._check_fitted()
        faiss = _faiss()

        def write(sub: Path) -> None:
            faiss.write_index(self.faiss_index_, str(sub / "faiss.index"))
            np.save(sub / "ids.npy", self.ids_)
            np.save(sub / "features.npy", np.asarray(self.features_))
            np.save(sub / "alive.npy", self.alive_)
            np.save(sub / "segs.npy", self.segs_)

        meta = {
            "format": _FORMAT,
            "version": version,
            "kind": self.kind_,
            "n": int(len(self.ids_)),
            "n_alive": self.n_alive,
            "dim": self.dim,
            "weights": self.weights_.tolist(),
            "params": self.params,
            "segments": list(self.segments_),
        }
        path = save_version(directory, write, meta, version=version)
        self.version_ = version
        self.unsaved_ = 0
        log.debug("saved %s index (version %s) to %s", self.kind_, version, path)
        return path

    @classmethod
    def load(cls, directory: str | os.PathLike[str]) -> FeatureIndex:
        """Read the index that ``<directory>/current.json`` points to.

        Raises
        ------
        StoreError
            When there is no index there or it is damaged.
        """
        faiss = _faiss()
        root = Path(directory)
        try:
            meta, sub = current(root)
            if meta.get("format") != _FORMAT:
                raise StoreError(f"unknown index format {meta.get('format')!r}", source=root)
            index = cls(**meta["params"])
            index.faiss_index_ = faiss.read_index(str(sub / "faiss.index"))
            index.ids_ = np.load(sub / "ids.npy")
            index.features_ = np.load(sub / "features.npy", mmap_mode="r")
            index.alive_ = np.load(sub / "alive.npy")
            has_segs = (sub / "segs.npy").exists()  # an index saved before they were kept
            n = len(index.ids_)
            index.segs_ = np.load(sub / "segs.npy") if has_segs else np.full(n, -1, np.int32)
            index.segments_ = tuple(meta.get("segments", ())) if has_segs else ()
        except (OSError, ValueError, KeyError, RuntimeError) as exc:
            raise StoreError(f"cannot read the feature index: {exc}", source=root) from exc
        index.weights_ = np.asarray(meta["weights"], np.float64)
        index.kind_, index.version_, index._pos = meta["kind"], meta["version"], None
        index._room, index.unsaved_ = None, 0
        n = len(index.ids_)
        sizes = (len(index.features_), len(index.alive_), len(index.segs_))
        if index.faiss_index_.ntotal != n or sizes != (n, n, n):
            raise StoreError("index files disagree on the number of vectors", source=root)
        if n and int(index.segs_.max()) >= len(index.segments_):
            raise StoreError("index names fewer segments than its rows point at", source=root)
        return index

    def __repr__(self) -> str:
        if not hasattr(self, "faiss_index_"):
            return f"FeatureIndex(kind={self.kind!r}, unfitted)"
        return f"FeatureIndex(kind={self.kind_!r}, n={self.n_alive}, d={self.dim}, version={self.version_})"


def _faiss() -> Any:
    return require("faiss", extra="faiss", feature="the feature index")


@contextlib.contextmanager
def _threads_for(n_queries: int) -> Iterator[None]:
    """A few queries run on one OpenMP thread.

    For one query faiss parallelises the flat scan across threads, which on a busy
    machine costs far more than it saves (``docs/results.md``, "Index").
    ``omp_set_num_threads`` sets the calling thread's own ICV, so other Python
    threads are unaffected.
    """
    if n_queries > _SMALL_BATCH:
        yield
        return
    faiss = _faiss()
    before = faiss.omp_get_max_threads()
    faiss.omp_set_num_threads(1)
    try:
        yield
    finally:
        faiss.omp_set_num_threads(before)


def _faiss_search(
    index: Any, x: NDArray[np.float32], k: int, *, ef_search: int | None = None
) -> NDArray[np.int64]:
    """faiss search of an index; a few queries run on one OpenMP thread."""
    faiss = _faiss()
    params = None if ef_search is None else faiss.SearchParametersHNSW(efSearch=ef_search)
    with _threads_for(len(x)):
        return index.search(x, k, params=params)[1]  # type: ignore[no-any-return]


def faiss_knn_l1(queries: NDArray[np.float32], vectors: NDArray[np.float32], k: int) -> Any:
    """(q, k) positions of the ``k`` nearest rows of ``vectors`` (n, d) to each of
    ``queries`` (q, d) by L1, exact (faiss's brute force over the arrays in place, float32;
    -1 pads); a few queries run on one OpenMP thread."""
    faiss = _faiss()
    with _threads_for(len(queries)):
        return faiss.knn(queries, vectors, int(k), metric=faiss.METRIC_L1)[1]


def faiss_pairwise_l1(queries: NDArray[np.float32], vectors: NDArray[np.float32]) -> Any:
    """(q, n) float32 L1 distances between ``queries`` (q, d) and every row of ``vectors``
    (n, d), both C-contiguous float32 (faiss's brute force; a few queries on one OpenMP
    thread)."""
    faiss = _faiss()
    with _threads_for(len(queries)):
        return faiss.pairwise_distances(queries, vectors, metric=faiss.METRIC_L1)


def _check_rows(
    ids: ArrayLike, features: ArrayLike, d: int
) -> tuple[NDArray[np.int64], NDArray[np.float32]]:
    ids_a = np.asarray(ids, dtype=np.int64).ravel()
    feats = np.asarray(features, dtype=np.float32)
    if len(ids_a) == 0:
        feats = feats.reshape(0, d)
    if feats.ndim != 2 or feats.shape != (len(ids_a), d):
        raise QueryError(f"expected shape ({len(ids_a)}, {d})", source=f"features {feats.shape}")
    if len(np.unique(ids_a)) != len(ids_a):
        raise QueryError("ids are not unique", source="ids")
    if not np.all(np.isfinite(feats)):
        raise QueryError("features contain NaN or inf", source="features")
    return ids_a, np.ascontiguousarray(feats)
