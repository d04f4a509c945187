"""A faiss index over the stored Eq. 1 feature vectors, kept in step with the store.

Eq. 2 is a weighted L1 distance, ``d(a, b) = sum_i w_i |a_i - b_i|`` with
``w = weights(config)``, which is the plain L1 distance between ``a * w`` and
``b * w``. The index therefore holds the *weighted* vectors under faiss's
``METRIC_L1``:

* ``kind="flat"`` -- ``IndexFlat(d, METRIC_L1)``, exact (default below
  ``hnsw_threshold`` vectors);
* ``kind="hnsw"`` -- ``IndexHNSWFlat(d, M, METRIC_L1)``, approximate;
* ``kind="auto"`` -- flat below ``hnsw_threshold`` vectors, HNSW above.

Either way faiss only proposes candidates (``max(oversample * k, min_candidates)``
of them); they are re-ranked with the exact Eq. 2 in float64 on the raw stored
features, ties broken by ascending id. faiss positions are mapped to shape ids with
a side array (``ids_``).

On disk (:func:`open_index`) the index lives in ``<store>/index/``: a pointer file
``current.json`` (replaced atomically) naming a directory ``v<version>-<token>/``
with ``faiss.index``, ``ids.npy``, ``features.npy`` and ``alive.npy``. The pointer
records the store version the index reflects; when the store has moved on, the index
is brought up to date: new ids are added, and deletions are tombstoned (HNSW) or
rebuilt (flat, or HNSW once a fifth of it is dead).

faiss is imported only when an index is built or loaded, so ``import shapedb``
stays light.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import threading
import uuid
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from shapedb.errors import ConfigError, NotFittedError, QueryError, StoreError, require

if TYPE_CHECKING:
    from shapedb.config import KernelConfig

__all__ = ["FeatureIndex", "open_index", "build_index", "on_commit", "INDEX_DIR"]

log = logging.getLogger(__name__)

INDEX_DIR = "index"
_POINTER = "current.json"
_FORMAT = 1
_KINDS = ("auto", "flat", "hnsw")
_REBUILD_DEAD_FRACTION = 0.2
_RERANK_CHUNK = 256
_SCAN_BLOCK = 65_536


def _faiss() -> Any:
    return require("faiss", extra="faiss", feature="the feature index")


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

    # ------------------------------------------------------------------ state
    @property
    def params(self) -> dict[str, Any]:
        """The constructor's settings, as a JSON-serialisable dict."""
        return {
            "kind": self.kind,
            "hnsw_threshold": self.hnsw_threshold,
            "hnsw_m": self.hnsw_m,
            "ef_construction": self.ef_construction,
            "ef_search": self.ef_search,
            "oversample": self.oversample,
            "min_candidates": self.min_candidates,
        }

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

    def _new_faiss(self, kind: str, d: int) -> Any:
        faiss = _faiss()
        if kind == "flat":
            return faiss.IndexFlat(d, faiss.METRIC_L1)
        index = faiss.IndexHNSWFlat(d, self.hnsw_m, faiss.METRIC_L1)
        index.hnsw.efConstruction = self.ef_construction
        index.hnsw.efSearch = self.ef_search
        return index

    def _weighted(self, features: NDArray[Any]) -> NDArray[np.float32]:
        return np.ascontiguousarray(np.asarray(features, np.float64) * self.weights_, np.float32)

    # -------------------------------------------------------------- building
    def fit(self, ids: ArrayLike, features: ArrayLike, weights: ArrayLike) -> FeatureIndex:
        """Build the index from scratch.

        Parameters
        ----------
        ids : (n,) int
            Shape ids, unique.
        features : (n, d) float
            Raw Eq. 1 feature vectors.
        weights : (d,) float
            Eq. 2 weights, ``shapedb.kernel.weights(config)``.

        Returns
        -------
        FeatureIndex
            ``self``.
        """
        w = np.asarray(weights, dtype=np.float64).ravel()
        ids_a, feats = _check_rows(ids, features, w.shape[0])
        self.weights_ = w
        self.kind_ = self._resolve_kind(len(ids_a))
        self.faiss_index_ = self._new_faiss(self.kind_, w.shape[0])
        self.ids_ = np.empty(0, np.int64)
        self.features_ = np.empty((0, w.shape[0]), np.float32)
        self.alive_ = np.empty(0, bool)
        self._pos: dict[int, int] | None = None
        self._append(ids_a, feats)
        log.info("built %s index of %d vectors (d=%d)", self.kind_, len(ids_a), w.shape[0])
        return self

    def _append(self, ids: NDArray[np.int64], features: NDArray[np.float32]) -> None:
        if len(ids):
            self.faiss_index_.add(self._weighted(features))
        self.ids_ = np.concatenate([self.ids_, ids])
        self.features_ = np.concatenate([np.asarray(self.features_), features])
        self.alive_ = np.concatenate([self.alive_, np.ones(len(ids), bool)])
        self._pos = None

    def add(self, ids: ArrayLike, features: ArrayLike) -> FeatureIndex:
        """Add new vectors (ids not already in the index).

        Parameters
        ----------
        ids : (m,) int
        features : (m, d) float
        """
        self._check_fitted()
        ids_a, feats = _check_rows(ids, features, self.dim)
        known = [i for i in ids_a.tolist() if i in self.positions]
        if known:
            raise QueryError("ids already in the index", source=f"ids {known[:5]}")
        self._append(ids_a, feats)
        return self

    def remove(self, ids: ArrayLike) -> FeatureIndex:
        """Tombstone vectors by id; they are never returned again.

        Parameters
        ----------
        ids : (m,) int
        """
        self._check_fitted()
        for i in np.asarray(ids, np.int64).ravel().tolist():
            p = self.positions.get(i)
            if p is not None:
                self.alive_[p] = False
        return self

    @property
    def positions(self) -> dict[int, int]:
        """Map shape id -> faiss position, live vectors only."""
        self._check_fitted()
        if self._pos is None:
            live = np.flatnonzero(self.alive_)
            self._pos = dict(zip(self.ids_[live].tolist(), live.tolist(), strict=True))
        return self._pos

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
        pos = self.positions
        new_mask = np.fromiter((i not in pos for i in ids_a.tolist()), bool, len(ids_a))
        old_ids = ids_a[~new_mask]
        old_pos = np.fromiter((pos[i] for i in old_ids.tolist()), np.int64, len(old_ids))
        changed = not np.array_equal(np.asarray(self.features_)[old_pos], feats[~new_mask])
        n_deleted = len(pos) - len(old_ids)
        dead_after = (len(self.ids_) - len(pos) + n_deleted) / max(
            len(self.ids_) + new_mask.sum(), 1
        )
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
            keep = set(old_ids.tolist())
            self.remove([i for i in pos if i not in keep])
        self._append(ids_a[new_mask], feats[new_mask])
        return "updated"

    # ------------------------------------------------------------- searching
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
            raise QueryError(
                f"expected feature vectors of length {self.dim}", source=f"query shape {q.shape}"
            )
        if not np.all(np.isfinite(q)):
            raise QueryError("feature vector has NaN or inf entries", source="query")
        k = int(k)
        if k < 1:
            raise QueryError("k must be >= 1", source=f"k={k}")
        if allowed is not None:
            pos = self.positions
            cand = np.array(
                sorted(
                    {pos[i] for i in np.asarray(allowed, np.int64).ravel().tolist() if i in pos}
                ),
                dtype=np.int64,
            )
            return self._scan(q, cand, k)
        n_live = self.n_alive
        if n_live == 0:
            return np.full((len(q), k), -1, np.int64), np.full((len(q), k), np.inf)
        dead = len(self.ids_) - n_live
        n_cand = max(self.oversample * k, self.min_candidates, k)
        n_cand = int(np.ceil(n_cand * len(self.ids_) / n_live)) if dead else n_cand
        n_cand = min(n_cand, len(self.ids_))
        if self.kind_ == "hnsw":
            self.faiss_index_.hnsw.efSearch = max(self.ef_search, n_cand)
        _, cand = self.faiss_index_.search(self._weighted(q), n_cand)
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
            d = np.where(
                valid, _weighted_l1(q[s : s + _RERANK_CHUNK], feats[cc], self.weights_), np.inf
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
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Brute-force exact search over every live vector (reference for recall)."""
        self._check_fitted()
        q = np.atleast_2d(np.asarray(queries, np.float64))
        return self._scan(q, np.flatnonzero(self.alive_), k)

    def features_of(self, shape_id: int) -> NDArray[np.float64] | None:
        """Stored feature vector of a shape id, or None when it is not indexed."""
        p = self.positions.get(int(shape_id))
        return None if p is None else np.asarray(self.features_[p], np.float64)

    # ----------------------------------------------------------- persistence
    def save(self, directory: str | os.PathLike[str], *, version: int | None = None) -> Path:
        """Write the index atomically under ``directory`` (an ``index/`` folder).

        A fresh sub-directory is written completely, then the pointer file
        ``current.json`` is replaced with :func:`os.replace`; older sub-directories
        are removed afterwards.
        """
        self._check_fitted()
        faiss = _faiss()
        root = Path(directory)
        root.mkdir(parents=True, exist_ok=True)
        name = f"v{version if version is not None else 'x'}-{uuid.uuid4().hex[:12]}"
        tmp = root / f".tmp-{name}"
        tmp.mkdir()
        faiss.write_index(self.faiss_index_, str(tmp / "faiss.index"))
        np.save(tmp / "ids.npy", self.ids_)
        np.save(tmp / "features.npy", np.asarray(self.features_))
        np.save(tmp / "alive.npy", self.alive_)
        os.replace(tmp, root / name)
        meta = {
            "format": _FORMAT,
            "dir": name,
            "version": version,
            "kind": self.kind_,
            "n": int(len(self.ids_)),
            "n_alive": self.n_alive,
            "dim": self.dim,
            "weights": self.weights_.tolist(),
            "params": self.params,
        }
        ptmp = root / f".{_POINTER}.{uuid.uuid4().hex[:8]}"
        ptmp.write_text(json.dumps(meta, indent=1))
        os.replace(ptmp, root / _POINTER)
        self.version_ = version
        for old in root.iterdir():
            if old.is_dir() and old.name != name and old.name.startswith("v"):
                shutil.rmtree(old, ignore_errors=True)
        log.debug("saved %s index (version %s) to %s", self.kind_, version, root / name)
        return root / name

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
            meta = json.loads((root / _POINTER).read_text())
            if meta.get("format") != _FORMAT:
                raise StoreError(f"unknown index format {meta.get('format')!r}", source=root)
            sub = root / meta["dir"]
            self = cls(**meta["params"])
            self.faiss_index_ = faiss.read_index(str(sub / "faiss.index"))
            self.ids_ = np.load(sub / "ids.npy")
            self.features_ = np.load(sub / "features.npy", mmap_mode="r")
            self.alive_ = np.load(sub / "alive.npy")
        except (OSError, ValueError, KeyError, RuntimeError) as exc:
            raise StoreError(f"cannot read the feature index: {exc}", source=root) from exc
        self.weights_ = np.asarray(meta["weights"], np.float64)
        self.kind_ = meta["kind"]
        self.version_ = meta["version"]
        self._pos = None
        if self.faiss_index_.ntotal != len(self.ids_) or len(self.features_) != len(self.ids_):
            raise StoreError("index files disagree on the number of vectors", source=root)
        if self.kind_ == "hnsw":
            self.faiss_index_.hnsw.efSearch = self.ef_search
        return self

    def __repr__(self) -> str:
        if not hasattr(self, "faiss_index_"):
            return f"FeatureIndex(kind={self.kind!r}, unfitted)"
        return f"FeatureIndex(kind={self.kind_!r}, n={self.n_alive}, d={self.dim}, version={self.version_})"


def _check_rows(
    ids: ArrayLike, features: ArrayLike, d: int
) -> tuple[NDArray[np.int64], NDArray[np.float32]]:
    ids_a = np.asarray(ids, dtype=np.int64).ravel()
    feats = np.asarray(features, dtype=np.float32)
    if len(ids_a) == 0:
        feats = feats.reshape(0, d)
    if feats.ndim != 2 or feats.shape != (len(ids_a), d):
        raise QueryError(
            f"expected features of shape ({len(ids_a)}, {d})", source=f"features {feats.shape}"
        )
    if len(np.unique(ids_a)) != len(ids_a):
        raise QueryError("ids are not unique", source="ids")
    if not np.all(np.isfinite(feats)):
        raise QueryError("features contain NaN or inf", source="features")
    return ids_a, np.ascontiguousarray(feats)


def _weighted_l1(
    q: NDArray[np.float64], x: NDArray[Any], w: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Eq. 2 between q (b, d) and candidate rows x (b, c, d): (b, c) float64."""
    return np.abs(x.astype(np.float64) - q[:, None, :]) @ w


# ------------------------------------------------------------------ store glue
_CACHE: dict[str, FeatureIndex] = {}
_LOCK = threading.Lock()


def _kernel_weights(config: KernelConfig) -> NDArray[np.float64]:
    from shapedb.kernel import weights

    return np.asarray(weights(config), dtype=np.float64)


def _store_key(db: Any) -> str:
    return os.path.realpath(os.fspath(db.store.path))


def open_index(
    db: Any, *, kind: str | None = None, rebuild: bool = False, **params: Any
) -> FeatureIndex:
    """The store's feature index, loaded, updated to the store's version, or built.

    Parameters
    ----------
    db : shapedb.Database
        Uses ``db.store`` (``path``, ``version``, ``features()``) and
        ``db.config.kernel``.
    kind : {"auto", "flat", "hnsw"}, optional
        Force an index type (rebuilding if the current one differs).
    rebuild : bool
        Rebuild from scratch even when up to date.
    **params
        Other :class:`FeatureIndex` settings for a (re)build.

    Returns
    -------
    FeatureIndex
        Up to date with ``db.store.version``; cached in-process per store path.
    """
    store = db.store
    key = _store_key(db)
    root = Path(key) / INDEX_DIR
    w = _kernel_weights(db.config.kernel)
    with _LOCK:
        version = store.version
        index = None if rebuild else _CACHE.get(key)
        if index is None and not rebuild and (root / _POINTER).exists():
            try:
                index = FeatureIndex.load(root)
            except StoreError as exc:
                log.warning("rebuilding the feature index: %s", exc)
        if index is not None and (
            index.weights_.shape != w.shape
            or not np.allclose(index.weights_, w, rtol=1e-12, atol=0)
            or (kind is not None and kind != index.kind)
        ):
            index = None  # kernel configuration or requested type changed
        if index is not None and index.version_ == version:
            _CACHE[key] = index
            return index
        ids, feats = store.features()
        feats = np.asarray(feats, np.float32).reshape(len(ids), w.shape[0])
        if index is None:
            settings = {**params, "kind": kind or params.get("kind", "auto")}
            index = FeatureIndex(**settings).fit(ids, feats, w)
            action = "built"
        else:
            action = index.sync(ids, feats)
        index.save(root, version=version)
        log.info("feature index %s at store version %s: %r", action, version, index)
        _CACHE[key] = index
        return index


def build_index(db: Any, *, kind: str = "auto", **params: Any) -> FeatureIndex:
    """Rebuild the store's index from scratch with the given settings."""
    return open_index(db, kind=kind, rebuild=True, **params)


def on_commit(db: Any, *args: Any, **kwargs: Any) -> None:
    """Store commit hook (entry point ``on_commit``): update an existing index.

    Only an index that was already built is updated (incrementally when possible);
    a store that was never searched gets its index lazily on the first search.
    """
    root = Path(_store_key(db)) / INDEX_DIR
    if _store_key(db) in _CACHE or (root / _POINTER).exists():
        open_index(db)


def _forget(db: Any) -> None:
    """Drop the in-process cache entry of a store (tests)."""
    _CACHE.pop(_store_key(db), None)
