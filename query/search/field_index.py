"""The field vector index: the stored shapes nearest by the L1 of their scaled field vectors.

The light field stage (:mod:`query.search.rerank_lightfield`) re-ranks version 4's ``K``
nearest shapes, and with ``StageTuning.field_candidates = K2 > 0`` also the
``K2`` nearest by the L1 distance of the scaled field vectors ``[depth / m_b, harmonic
/ m_h]`` (:meth:`query.search.field_fusion.FieldFusion.scaled`) not among those ``K``. This
module finds those ``K2``: a faiss ``IndexFlat(dim, METRIC_L1)`` over the scaled stored
vectors proposes (a float32 numpy scan up to :data:`SCAN_MAX` vectors, which is faster
there), and the exact float64 L1 of the float32 scaled vectors orders (ties by ascending
id); a search restricted to some ids (a ``where`` filter, an evaluation over the
labelled shapes) scans them exactly instead.

One index per store version (:func:`field_index`): built from the store's
``field_vector`` column at a version's first search that asks for it, shared by every
search of that version, never written to disk (a flat index costs one pass over the
column). Records without a field vector are left out.
"""

from __future__ import annotations

import logging
import os
import threading
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from query.search.field_fusion import FIELD, FieldFusion

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = ["FieldIndex", "field_index", "SCAN_MAX"]

log = logging.getLogger(__name__)

#: Extra proposals asked past k, so that float32 rounding cannot push a neighbour out
#: before the exact float64 order.
_MARGIN = 16
#: Up to this many vectors a float32 numpy scan proposes the candidates (faiss's flat L1
#: search is slower per vector than numpy's at the field vector's length); beyond, the
#: faiss index.
SCAN_MAX = 65_536
_SCAN_BLOCK = 4096
_NO_ID = np.iinfo(np.int64).max


class FieldIndex:
    """Exact nearest neighbours by the L1 distance of scaled field vectors.

    Parameters
    ----------
    ids : (n,) int
        Shape ids, unique.
    vectors : (n, d) float
        Their scaled field vectors (:meth:`FieldFusion.scaled`), finite.
    """

    def __init__(self, ids: ArrayLike, vectors: ArrayLike) -> None:
        ids_a = np.asarray(ids, np.int64).ravel()
        order = np.argsort(ids_a, kind="stable")
        self.ids_ = ids_a[order]
        self.vectors_ = np.ascontiguousarray(np.asarray(vectors, np.float32)[order])
        if len(np.unique(self.ids_)) != len(self.ids_):
            raise ValueError("field index: ids must be unique")
        self._faiss: Any = None

    def __len__(self) -> int:
        return len(self.ids_)

    def _index(self) -> Any:
        if self._faiss is None:
            from shapedb.errors import require

            faiss = require("faiss", extra="faiss", feature="the field vector index")
            self._faiss = faiss.IndexFlat(self.vectors_.shape[1], faiss.METRIC_L1)
            if len(self.ids_):
                self._faiss.add(self.vectors_)
        return self._faiss

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
            Nearest first, ties by ascending id; -1 pads.
        distances : (q, k) float64
            L1 distances (float64 over the float32 vectors); inf pads.
        """
        q = np.atleast_2d(np.asarray(queries, np.float64))
        k = int(k)
        out_i = np.full((len(q), k), -1, np.int64)
        out_d = np.full((len(q), k), np.inf)
        ok = np.all(np.isfinite(q), axis=1)
        if not len(self.ids_) or not ok.any() or k < 1:
            return out_i, out_d
        if allowed is not None:
            cand = np.flatnonzero(np.isin(self.ids_, np.asarray(allowed, np.int64)))
            for row in np.flatnonzero(ok):
                out_i[row], out_d[row] = self._exact(q[row], cand, k)
            return out_i, out_d
        n_cand = min(k + _MARGIN, len(self.ids_))
        rows = np.flatnonzero(ok)
        q32 = np.ascontiguousarray(q[rows], np.float32)
        if len(self.ids_) > SCAN_MAX:
            _, found = self._index().search(q32, n_cand)
        else:  # a float32 scan proposes as the flat index would, faster at this size
            found = np.empty((len(rows), n_cand), np.int64)
            for at in range(len(rows)):
                d = np.abs(self.vectors_ - q32[at]).sum(axis=1)
                found[at] = np.argpartition(d, n_cand - 1)[:n_cand]
        for at, row in enumerate(rows):
            cand = found[at][found[at] >= 0]
            out_i[row], out_d[row] = self._exact(q[row], cand, k)
        return out_i, out_d

    def _exact(
        self, query: NDArray[np.float64], positions: NDArray[Any], k: int
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """(k,) ids and distances of the nearest of ``positions``, exact, ties by id."""
        out_i = np.full(k, -1, np.int64)
        out_d = np.full(k, np.inf)
        best_i = np.empty(0, np.int64)
        best_d = np.empty(0)
        positions = np.asarray(positions, np.int64)
        for lo in range(0, len(positions), _SCAN_BLOCK):
            p = positions[lo : lo + _SCAN_BLOCK]
            d = np.abs(self.vectors_[p].astype(np.float64) - query).sum(axis=1)
            all_i = np.concatenate([best_i, self.ids_[p]])
            all_d = np.concatenate([best_d, d])
            order = np.lexsort((all_i, all_d))[:k]
            best_i, best_d = all_i[order], all_d[order]
        out_i[: len(best_i)], out_d[: len(best_d)] = best_i, best_d
        return out_i, out_d


#: Field indexes by (store path, store version): the most recent few.
_INDEXES: dict[tuple[str, int], tuple[Any, FieldIndex]] = {}
_KEEP = 4
_LOCK = threading.Lock()


def field_index(db: StoreHandle) -> FieldIndex:
    """The shared :class:`FieldIndex` of ``db``'s store at its current version.

    Built from the ``field_vector`` column, scaled by ``db.config``'s fusion
    (:meth:`FieldFusion.scaled`); rebuilt when the store's version or its fusion
    scales change. A store without field vectors gets an empty index.
    """
    fusion = FieldFusion.from_config(db.config)
    key = (os.fspath(db.store.path), int(db.store.version))
    scales = (fusion.m_b, fusion.m_h, fusion.depth, fusion.harmonic)
    with _LOCK:
        cached = _INDEXES.get(key)
        if cached is not None and cached[0] == scales:
            return cached[1]
    ids: list[int] = []
    rows: list[NDArray[np.float32]] = []
    if fusion.stored:
        t = db.store.shapes(["id", FIELD])
        for i, v in zip(t.column("id").to_pylist(), t.column(FIELD).to_pylist(), strict=True):
            if v is not None:
                ids.append(int(i))
                rows.append(np.asarray(v, np.float32))
    dim = fusion.scaled(np.zeros((1, _dim(db, rows)))).shape[1]
    vectors = fusion.scaled(np.stack(rows)) if rows else np.zeros((0, dim), np.float32)
    index = FieldIndex(np.asarray(ids, np.int64), vectors)
    log.info("field vector index of %d shapes at store version %s", len(ids), key[1])
    with _LOCK:
        _INDEXES[key] = (scales, index)
        while len(_INDEXES) > _KEEP:
            _INDEXES.pop(next(iter(_INDEXES)))
    return index


def _dim(db: StoreHandle, rows: list[NDArray[np.float32]]) -> int:
    if rows:
        return int(rows[0].shape[0])
    if not FieldFusion.from_config(db.config).stored:
        return 0
    from shapedb.signature.field_vector import field_vector_dim

    return int(field_vector_dim(db.config.field_vector))
