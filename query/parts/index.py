"""A faiss index over the neighbourhood-subgraph features of every node of every shape.

Corpus part search asks: which neighbourhood subgraph ``G[N(u, K)]`` of which stored
shape is most like the query part? Each stored shape of n balls contributes n vectors
(:func:`shapedb.signature.subgraph.neighbourhood_features`: Eq. 1 plus the size and centre
blocks, d = 3 n_r + 2 = 32 by default, :func:`shapedb.signature.subgraph.part_dim`), so a
store of 1e4 shapes of 512 balls holds five million. As in :mod:`query.search.index`, the
part distance (Eq. 2 extended) is a weighted L1 distance, so faiss holds
``f * weights``:

* below ``ivf_threshold`` vectors, ``IndexFlat(d, METRIC_L1)`` (exact);
* above, ``IndexIVFPQ`` (kind ``"ivf"``): an L2 coarse quantizer and :data:`PQ_M`-byte
  product-quantised codes of the weighted vectors, probing ``nprobe`` lists. PQ knows
  L2, not L1: it proposes at least :data:`PQ_MIN_CANDIDATES` candidates by L2 and the
  exact L1 re-rank orders them. faiss holds only the codes; the raw float32 features
  stay on disk, memory-mapped, and are read for the candidates alone.

faiss only proposes candidates; they are re-ranked exactly in float64 on the raw
features and grouped by shape (at most ``per_shape`` results per shape, default 1:
neighbouring nodes of one shape have nearly identical neighbourhoods; with
``per_shape > 1`` the matches kept within a shape are chosen greedily so that their
node sets overlap by at most ``overlap``, Jaccard, default 0.0: disjoint). When the
candidates hold fewer than k distinct shapes the search widens (more candidates,
more lists) and finally falls back to the exact scan.

Per shape the index also keeps the contact edges of its part graph (the contacts
found again from the balls at ``PartConfig.contact_tol_cells``,
:func:`shapedb.signature.subgraph.part_graph`), so that a hit's node set ``N(u, K)`` is known
without reading the store.

On disk, beside the store: ``<store>/parts/<PartConfig fingerprint>/current.json``
(replaced atomically) names ``v<version>-<token>/`` holding the per-shape arrays
``shapes.npy``, ``node_ptr.npy``, ``edge_ptr.npy``, ``alive.npy`` (rewritten each save)
and the per-row arrays as chunk files ``features-<k>.npy``, ``edges-<k>.npy`` and, for
IVF, ``codes-<k>.npy`` (faiss's standalone codes) beside ``faiss_trained.npy`` (the
trained, empty index): a save hard-links the chunks already on disk and writes the new
rows as a new chunk (:class:`query.parts.chunks.RowChunks`), so a commit costs about
what it adds. Loading memory-maps the features and edges and refills faiss from the
codes. When the store version has moved, new shapes are
featurised from the store's balls and added, deleted ones tombstoned (the index is
compacted once a fifth of it is dead). The configuration of an index written by an
older version is read through :mod:`shapedb.config.migrations` (:func:`read_part_config`).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from query.parts.chunks import RowChunks
from query.search.versioned import current, save_version
from shapedb.config.part import PartConfig
from shapedb.errors import NotFittedError, QueryError, StoreError, require
from shapedb.signature.subgraph import neighbourhood_features_many, part_dim, part_weights

if TYPE_CHECKING:
    pass

__all__ = ["PartIndex", "read_part_config", "PARTS_DIR", "FEATURE_BATCH"]

log = logging.getLogger(__name__)

PARTS_DIR = "parts"
_FORMAT = 2
_DEAD_FRACTION = 0.2
_SCAN_BLOCK = 262_144
FEATURE_BATCH = 1_024  # shapes featurised at once (float64 scratch of ~16 MB a 1,000)
#: PQ sub-quantizers of the compressed index (8 bits each, 2 of d = 32 dims apiece): 16 B a
#: vector (recall below, with PQ_MIN_CANDIDATES).
PQ_M = 16
#: Fewest candidates the compressed index proposes for the exact L1 re-rank: recall@10
#: 0.988 with 256 and 1.000 with 1,024 (p50 1.1 ms) at 10^6 vectors of real records.
PQ_MIN_CANDIDATES = 1_024
#: Most IVF lists by default: assigning a vector costs nlist * d (8.7 s a million vectors
#: at 4,096), while a query at 5 x 10^6 vectors probing 32 of 4,096 lists took 1.8 ms.
MAX_NLIST = 4_096
#: faiss is rebuilt (IVF lists and codebooks trained again) once the index holds this many
#: times the vectors it was trained on: each row is re-encoded O(1) times on average.
_RETRAIN_GROWTH = 4


def read_part_config(data: dict[str, Any]) -> PartConfig:
    """The :class:`PartConfig` of a stored part index of any version (:mod:`shapedb.config.migrations`)."""
    return PartConfig.from_dict(data)


def _faiss() -> Any:
    return require("faiss", extra="faiss", feature="the part index")


class PartIndex:
    """Nearest neighbourhood subgraphs under Eq. 2, grouped by shape.

    Parameters
    ----------
    config : PartConfig
        Neighbourhood range and kernel of the stored features.
    ivf_threshold : int
        From this many vectors an IVF index is built instead of a flat one.
    nlist : int, optional
        IVF lists; default ``2 * sqrt(n)`` rounded to a power of two, at most
        :data:`MAX_NLIST`.
    nprobe : int
        IVF lists probed per query (doubled on each widening).
    oversample : int
        Candidates asked from faiss per wanted result, before grouping by shape.
    min_candidates : int
        Lower bound on the number of candidates.

    Attributes
    ----------
    features_ : (N, d) float32
        Raw features, one row per (shape, node).
    shapes_ : (S,) int64
        Shape ids, in the order their rows appear.
    node_ptr_ : (S + 1,) int64
        Rows of shape s are ``node_ptr_[s]:node_ptr_[s + 1]``; row - ``node_ptr_[s]``
        is the node.
    edge_ptr_ : (S + 1,) int64, edges_ : (E, 2) int32
        Contact edges of shape s (local node numbers) are ``edges_[edge_ptr_[s]:...]``.
    alive_ : (S,) bool
        False for shapes deleted from the store (tombstones).
    version_ : int or None
        Store version the index reflects.
    """

    def __init__(
        self,
        config: PartConfig | None = None,
        *,
        ivf_threshold: int = 500_000,
        nlist: int | None = None,
        nprobe: int = 32,
        oversample: int = 16,
        min_candidates: int = 256,
    ) -> None:
        self.config = config if config is not None else PartConfig()
        self.ivf_threshold = int(ivf_threshold)
        self.nlist = nlist
        self.nprobe = int(nprobe)
        self.oversample = int(oversample)
        self.min_candidates = int(min_candidates)
        self.version_: int | None = None
        self._order: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None

    # ------------------------------------------------------------------ building
    @property
    def params(self) -> dict[str, Any]:
        """Constructor settings (without ``config``), JSON-serialisable."""
        keys = ("ivf_threshold", "nlist", "nprobe", "oversample", "min_candidates")
        return {k: getattr(self, k) for k in keys}

    def _check_fitted(self) -> None:
        if not hasattr(self, "features_"):
            raise NotFittedError("PartIndex used before fit()", source="PartIndex")

    @property
    def weights(self) -> NDArray[np.float64]:
        """(d,) weights of the part distance (:func:`shapedb.signature.subgraph.part_weights`)."""
        return part_weights(self.config)

    def fit(self, ids: ArrayLike, graphs: list[Any]) -> PartIndex:
        """Index the neighbourhoods of every node of ``graphs``.

        Parameters
        ----------
        ids : (S,) int
            Shape ids, unique.
        graphs : list of ContactGraph, Decomposition or (radii (n,), edges (m, 2))
            One graph per id.

        Returns
        -------
        PartIndex
            ``self``.
        """
        return self.fit_batches([(ids, graphs)])

    def fit_batches(
        self, batches: Iterable[tuple[ArrayLike, list[Any]]], *, spill: Path | None = None
    ) -> PartIndex:
        """:meth:`fit` over batches of ``(ids, graphs)``; with ``spill`` (a directory on
        the index's file system) each batch's rows are written there and memory-mapped,
        so that the build holds one batch in memory (a save links those files)."""
        self.shapes_ = np.zeros(0, np.int64)
        self.node_ptr_ = np.zeros(1, np.int64)
        self.edge_ptr_ = np.zeros(1, np.int64)
        self.edges_ = RowChunks(np.int32, (2,))
        self.alive_ = np.zeros(0, bool)
        self.features_ = RowChunks(np.float32, (part_dim(self.config),))
        for ids, graphs in batches:
            self._append(ids, graphs)
            if spill is not None:
                self.features_.spill(spill)
                self.edges_.spill(spill)
        self._build_faiss()
        return self

    def _append(self, ids: ArrayLike, graphs: list[Any]) -> None:
        ids_a = np.asarray(ids, dtype=np.int64).ravel()
        if len(ids_a) != len(graphs):
            raise QueryError(f"{len(ids_a)} ids for {len(graphs)} graphs", source="PartIndex")
        if len(np.unique(np.concatenate([self.shapes_[self.alive_], ids_a]))) != (
            int(self.alive_.sum()) + len(ids_a)
        ):
            raise QueryError("shape ids are not unique", source="PartIndex")
        from shapedb.signature.subgraph import graph_arrays

        arrays = [graph_arrays(g) for g in graphs]
        sizes = np.array([len(r) for r, _ in arrays], np.int64)
        offsets = np.r_[0, np.cumsum(sizes)].astype(np.int64)
        feats = np.empty((int(offsets[-1]), part_dim(self.config)), np.float32)
        for b in range(0, len(arrays), FEATURE_BATCH):  # float64 scratch of one batch
            f, _ = neighbourhood_features_many(arrays[b : b + FEATURE_BATCH], self.config)
            feats[offsets[b] : offsets[b] + len(f)] = f
        n_edges = np.array([len(e) for _, e in arrays], np.int64)
        self.features_.append(feats)
        self.shapes_ = np.concatenate([self.shapes_, ids_a])
        self.node_ptr_ = np.concatenate([self.node_ptr_, self.node_ptr_[-1] + offsets[1:]])
        self.edge_ptr_ = np.concatenate([self.edge_ptr_, self.edge_ptr_[-1] + np.cumsum(n_edges)])
        if len(arrays):
            self.edges_.append(np.concatenate([e for _, e in arrays]).astype(np.int32))
        self.alive_ = np.concatenate([self.alive_, np.ones(len(ids_a), bool)])
        self._order = None

    def _weighted(self, x: ArrayLike) -> NDArray[np.float32]:
        return np.ascontiguousarray(np.asarray(x, np.float64) * self.weights, np.float32)

    def _build_faiss(self) -> None:
        faiss = _faiss()
        n, d = self.features_.shape
        self.kind_ = "ivf" if n >= self.ivf_threshold else "flat"
        self.trained_n_ = int(n)
        if self.kind_ == "flat":
            self.faiss_ = faiss.IndexFlat(d, faiss.METRIC_L1)
        else:  # L2 on the weighted vectors proposes, the exact L1 re-rank decides
            nlist = self.nlist or min(int(2 ** np.round(np.log2(2 * np.sqrt(n)))), MAX_NLIST)
            m = PQ_M if d % PQ_M == 0 else 1
            self.faiss_ = faiss.IndexIVFPQ(faiss.IndexFlatL2(d), d, nlist, m, 8)
            sample = np.random.default_rng(0).choice(n, min(n, 64 * nlist), replace=False)
            self.faiss_.train(self._weighted(self.features_.take(np.sort(sample))))
            self.trained_ = faiss.serialize_index(self.faiss_)
            self.codes_ = RowChunks(np.uint8, (self.faiss_.sa_code_size(),))
        self._add_faiss(0)
        log.info("built %s part index: %d vectors of %d shapes", self.kind_, n, len(self.shapes_))

    def _add_faiss(self, start: int) -> None:
        """Add the rows from ``start`` to faiss (and, compressed, to ``codes_``)."""
        codes = []
        for s in range(start, len(self.features_), _SCAN_BLOCK * 4):
            rows = np.arange(s, min(s + _SCAN_BLOCK * 4, len(self.features_)))
            x = self._weighted(self.features_.take(rows))
            if self.kind_ == "flat":
                self.faiss_.add(x)
            else:
                codes.append(self.faiss_.sa_encode(x))
                self.faiss_.add_sa_codes(codes[-1])
        if codes:
            self.codes_.append(np.concatenate(codes))

    def add(self, ids: ArrayLike, graphs: list[Any]) -> PartIndex:
        """Add shapes (their graphs) to a fitted index."""
        self._check_fitted()
        start = len(self.features_)
        self._append(ids, graphs)
        n = len(self.features_)
        if (self.kind_ == "flat" and n >= self.ivf_threshold) or (
            self.kind_ != "flat" and n > _RETRAIN_GROWTH * max(self.trained_n_, 1)
        ):
            self._build_faiss()  # grown past the flat index, or far past its training
        else:
            self._add_faiss(start)
        return self

    def remove(self, ids: ArrayLike) -> PartIndex:
        """Tombstone shapes by id; compact once a fifth of the vectors is dead."""
        self._check_fitted()
        gone = np.isin(self.shapes_, np.asarray(ids, np.int64))
        self.alive_[gone] = False
        sizes = np.diff(self.node_ptr_)
        if sizes[~self.alive_].sum() > _DEAD_FRACTION * max(sizes.sum(), 1):
            self._compact()
        return self

    def _compact(self) -> None:
        keep = np.flatnonzero(self.alive_)
        rows = _concat_ranges(self.node_ptr_, keep)
        erows = _concat_ranges(self.edge_ptr_, keep)
        sizes, esizes = np.diff(self.node_ptr_)[keep], np.diff(self.edge_ptr_)[keep]
        self.features_ = self.features_.select(rows)
        self.edges_ = self.edges_.select(erows)
        self.shapes_ = self.shapes_[keep]
        self.node_ptr_ = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.edge_ptr_ = np.concatenate([[0], np.cumsum(esizes)]).astype(np.int64)
        self.alive_ = np.ones(len(keep), bool)
        self._order = None
        self._build_faiss()

    # ------------------------------------------------------------------ lookups
    @property
    def n_vectors(self) -> int:
        """Live vectors."""
        self._check_fitted()
        return int(np.diff(self.node_ptr_)[self.alive_].sum())

    def _slot(self, shape_id: int) -> int:
        if self._order is None:
            live = np.flatnonzero(self.alive_)
            o = np.argsort(self.shapes_[live], kind="stable")
            self._order = (self.shapes_[live][o], live[o])
        keys, pos = self._order
        i = int(np.searchsorted(keys, shape_id))
        if i >= len(keys) or keys[i] != shape_id:
            raise QueryError("shape is not in the part index", source=shape_id)
        return int(pos[i])

    def features_of(self, shape_id: int) -> NDArray[np.float64]:
        """(n, d) float64: the part features of every node of a stored shape."""
        s = self._slot(int(shape_id))
        rows = np.arange(self.node_ptr_[s], self.node_ptr_[s + 1])
        return np.asarray(self.features_.take(rows), np.float64)

    def graph_of(self, shape_id: int) -> tuple[int, NDArray[np.int32]]:
        """(number of nodes, edges (m, 2) int32) of a stored shape."""
        s = self._slot(int(shape_id))
        n = int(self.node_ptr_[s + 1] - self.node_ptr_[s])
        return n, self.edges_.take(np.arange(self.edge_ptr_[s], self.edge_ptr_[s + 1]))

    def node_set(self, shape_id: int, node: int) -> NDArray[np.int64]:
        """N(node, K) in a stored shape, sorted."""
        n, e = self.graph_of(shape_id)
        if not 0 <= node < n:
            raise QueryError(f"node {node} is not in a graph of {n} nodes", source=shape_id)
        seen = np.array([node], np.int64)
        for _ in range(self.config.hops):  # BFS on the edge list: m is small
            touch = np.isin(e, seen)
            grown = np.union1d(seen, e[touch[:, ::-1]])
            if len(grown) == len(seen):
                break
            seen = grown
        return seen

    # ------------------------------------------------------------------ search
    def _group(
        self,
        pos: NDArray[np.int64],
        d: NDArray[np.float64],
        k: int,
        per_shape: int,
        overlap: float | None = 0.0,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
        """Best ``per_shape`` rows per shape, top k overall: (shape ids, nodes, distances).

        With ``overlap`` (not None) and ``per_shape > 1``, the rows kept within a shape
        are taken greedily in distance order, skipping a row whose N(u, K) overlaps
        (Jaccard) a kept one of the same shape by more than ``overlap``.
        """
        slot = np.searchsorted(self.node_ptr_, pos, side="right") - 1
        ok = self.alive_[slot] & np.isfinite(d)
        pos, d, slot = pos[ok], d[ok], slot[ok]
        sid = self.shapes_[slot]
        node = pos - self.node_ptr_[slot]
        order = np.lexsort((node, sid, d))
        if overlap is not None and per_shape > 1:
            sel = self._suppress(sid, node, order, k, per_shape, overlap)
            return sid[sel], node[sel], d[sel]
        sid_o = sid[order]
        # rank of each row within its shape, in distance order
        srt = np.argsort(sid_o, kind="stable")
        starts = np.r_[0, np.flatnonzero(np.diff(sid_o[srt])) + 1]
        rank = np.empty(len(order), np.int64)
        rank[srt] = np.arange(len(srt)) - np.repeat(starts, np.diff(np.r_[starts, len(srt)]))
        first = rank < per_shape
        sel = order[first][:k]
        return sid[sel], node[sel], d[sel]

    def _suppress(
        self,
        sid: NDArray[np.int64],
        node: NDArray[np.int64],
        order: NDArray[np.int64],
        k: int,
        per_shape: int,
        overlap: float,
    ) -> NDArray[np.int64]:
        """Greedy per-shape NMS over rows in ``order``: positions kept (<= k)."""
        kept: dict[int, list[NDArray[np.int64]]] = {}
        out: list[int] = []
        for i in order.tolist():
            s = int(sid[i])
            have = kept.setdefault(s, [])
            if len(have) >= per_shape:
                continue
            ns = self.node_set(s, int(node[i]))
            if any(_jaccard(ns, h) > overlap for h in have):
                continue
            have.append(ns)
            out.append(i)
            if len(out) == k:
                break
        return np.asarray(out, np.int64)

    def search(
        self,
        query: ArrayLike,
        k: int = 10,
        *,
        per_shape: int = 1,
        allowed: ArrayLike | None = None,
        overlap: float | None = 0.0,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
        """The k stored neighbourhoods nearest to one query feature, exact distance order.

        Parameters
        ----------
        query : (d,) float
            Raw part feature of the query.
        k : int
            Results wanted.
        per_shape : int
            At most this many results per shape.
        allowed : (m,) int, optional
            Only these shape ids (exact scan over their nodes).
        overlap : float or None
            Within a shape, skip matches whose node sets overlap a better one's by
            more than this (Jaccard; only matters for ``per_shape > 1``); None: off.

        Returns
        -------
        shape_ids : (<= k,) int64
        nodes : (<= k,) int64
            Centre node u of each matching neighbourhood N(u, K).
        distances : (<= k,) float64
            Eq. 2 distances, ascending; ties by shape id, then node.
        """
        self._check_fitted()
        q = self._query(query)
        k, per_shape = int(k), int(per_shape)
        if k < 1 or per_shape < 1:
            raise QueryError("k and per_shape must be >= 1", source=f"k={k}, per_shape={per_shape}")
        if allowed is not None:
            slots = np.flatnonzero(
                np.isin(self.shapes_, np.asarray(allowed, np.int64)) & self.alive_
            )
            return self._scan(q, _concat_ranges(self.node_ptr_, slots), k, per_shape, overlap)
        total = len(self.features_)
        n_cand = max(self.oversample * k * per_shape, self.min_candidates)
        if self.kind_ != "flat":  # L2 on PQ codes proposes: re-rank a wider set by L1
            n_cand = max(n_cand, PQ_MIN_CANDIDATES)
        nprobe = self.nprobe
        faiss = _faiss()
        while n_cand < total:
            params = None
            if self.kind_ != "flat":
                params = faiss.SearchParametersIVF(nprobe=min(nprobe, self.faiss_.nlist))
            before = faiss.omp_get_max_threads()
            faiss.omp_set_num_threads(1)
            try:
                cand = self.faiss_.search(self._weighted(q[None]), n_cand, params=params)[1][0]
            finally:
                faiss.omp_set_num_threads(before)
            cand = cand[cand >= 0]
            x = np.asarray(self.features_.take(np.sort(cand)), np.float64)
            d = np.abs(x - q) @ self.weights
            out = self._group(np.sort(cand), d, k, per_shape, overlap)
            if len(out[0]) >= k:
                return out
            n_cand, nprobe = 4 * n_cand, 4 * nprobe
        return self._scan(q, np.arange(total, dtype=np.int64), k, per_shape, overlap)

    def exact_search(
        self, query: ArrayLike, k: int = 10, *, per_shape: int = 1, overlap: float | None = 0.0
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
        """Brute force over every live vector (the reference for recall)."""
        self._check_fitted()
        pos = np.arange(len(self.features_))
        return self._scan(self._query(query), pos, int(k), per_shape, overlap)

    def _query(self, query: ArrayLike) -> NDArray[np.float64]:
        q = np.asarray(query, np.float64).ravel()
        dim = part_dim(self.config)
        if q.shape != (dim,) or not np.all(np.isfinite(q)):
            raise QueryError(f"part feature must be {dim} finite values", source=f"shape {q.shape}")
        # the stored features are float32: quantise the query the same way, so that an
        # identical stored subgraph is at distance exactly 0 (similarity 1.0)
        return q.astype(np.float32).astype(np.float64)

    def _scan(
        self,
        q: NDArray[np.float64],
        pos: NDArray[np.int64],
        k: int,
        per_shape: int,
        overlap: float | None = 0.0,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
        w = self.weights
        best: list[tuple[NDArray[np.int64], NDArray[np.float64]]] = []
        for s in range(0, len(pos), _SCAN_BLOCK):
            p = pos[s : s + _SCAN_BLOCK]
            d = np.abs(np.asarray(self.features_.take(p), np.float64) - q) @ w
            if len(d) > 64 * k * per_shape:  # keep a generous prefix for grouping
                thr = np.partition(d, 64 * k * per_shape)[64 * k * per_shape]
                keep = d <= thr
                p, d = p[keep], d[keep]
            best.append((p, d))
        if not best:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        p = np.concatenate([b[0] for b in best])
        d = np.concatenate([b[1] for b in best])
        out = self._group(p, d, k, per_shape, overlap)
        if len(out[0]) < k and len(p) < len(pos):  # prefix too short to hold k shapes
            d = np.abs(np.asarray(self.features_.take(pos), np.float64) - q) @ w
            out = self._group(pos, d, k, per_shape, overlap)
        return out

    # ------------------------------------------------------------------ persistence
    _ARRAYS = ("shapes", "node_ptr", "edge_ptr", "alive")
    _CHUNKED = ("features", "edges", "codes")

    def save(self, directory: str | os.PathLike[str], *, version: int | None = None) -> Path:
        """Write the index atomically under ``directory`` (pointer file + fresh sub-dir).

        The per-shape arrays are written whole (S rows); features, edges and faiss codes
        are chunk files, those already on disk hard-linked (:class:`RowChunks`), so a
        commit writes about what it added. Afterwards the chunks are memory-mapped.
        """
        self._check_fitted()
        chunked = [c for c in self._CHUNKED if c != "codes" or self.kind_ != "flat"]
        sizes: dict[str, list[int]] = {}

        def write(sub: Path) -> None:
            for a in self._ARRAYS:
                np.save(sub / f"{a}.npy", np.asarray(getattr(self, f"{a}_")))
            for c in chunked:
                sizes[c] = getattr(self, f"{c}_").save(sub, c)
            if self.kind_ != "flat":
                np.save(sub / "faiss_trained.npy", self.trained_)

        meta = {
            "format": _FORMAT,
            "version": version,
            "kind": self.kind_,
            "config": self.config.to_dict(),
            "params": self.params,
            "n": int(len(self.features_)),
            "chunks": sizes,
            "trained_n": self.trained_n_,
        }
        path = save_version(directory, write, meta, version=version)
        for c in chunked:  # the saved files, memory-mapped: the next save links them
            old = getattr(self, f"{c}_")
            setattr(self, f"{c}_", RowChunks.load(path, c, sizes[c], old.dtype, old.tail))
        self.version_ = version
        return path

    @classmethod
    def load(cls, directory: str | os.PathLike[str]) -> PartIndex:
        """Read the index ``<directory>/current.json`` points to (:class:`StoreError` if bad).

        Features and edges are memory-mapped; a compressed index's codes are read into
        faiss chunk by chunk.
        """
        root = Path(directory)
        try:
            meta, sub = current(root)
            if meta.get("format") != _FORMAT:
                raise StoreError(f"unknown part index format {meta.get('format')!r}", source=root)
            index = cls(read_part_config(meta["config"]), **meta["params"])
            for a in cls._ARRAYS:
                setattr(index, f"{a}_", np.load(sub / f"{a}.npy"))
            sizes = meta["chunks"]
            d = part_dim(index.config)
            index.features_ = RowChunks.load(sub, "features", sizes["features"], np.float32, (d,))
            index.edges_ = RowChunks.load(sub, "edges", sizes["edges"], np.int32, (2,))
            index.kind_ = meta["kind"]
            index.trained_n_ = int(meta["trained_n"])
            if index.kind_ != "flat":
                index._read_codes(sub, sizes["codes"])
        except (OSError, ValueError, KeyError, TypeError, RuntimeError) as exc:
            raise StoreError(f"cannot read the part index: {exc}", source=root) from exc
        if index.kind_ == "flat":
            index._build_faiss()
        index.version_, index._order = meta["version"], None
        if index.faiss_.ntotal != len(index.features_):
            raise StoreError("part index files disagree on the number of vectors", source=root)
        return index

    def _read_codes(self, sub: Path, sizes: list[int]) -> None:
        """The trained empty faiss index, filled with the saved codes chunk by chunk."""
        faiss = _faiss()
        self.trained_ = np.load(sub / "faiss_trained.npy")
        self.faiss_ = faiss.deserialize_index(self.trained_)
        width = self.faiss_.sa_code_size()
        for k in range(len(sizes)):  # read, not mapped: faiss keeps its own copy
            self.faiss_.add_sa_codes(np.load(sub / f"codes-{k}.npy"))
        self.codes_ = RowChunks.load(sub, "codes", sizes, np.uint8, (width,))

    def __repr__(self) -> str:
        if not hasattr(self, "features_"):
            return "PartIndex(unfitted)"
        return (
            f"PartIndex(kind={self.kind_!r}, shapes={int(self.alive_.sum())}, "
            f"vectors={self.n_vectors}, hops={self.config.hops}, version={self.version_})"
        )


def _jaccard(a: NDArray[np.int64], b: NDArray[np.int64]) -> float:
    """|a & b| / |a | b| of two sorted node sets."""
    inter = len(np.intersect1d(a, b, assume_unique=True))
    return inter / max(len(a) + len(b) - inter, 1)


def _concat_ranges(ptr: NDArray[np.int64], slots: NDArray[np.int64]) -> NDArray[np.int64]:
    from shapedb.signature.subgraph import concat_aranges

    return concat_aranges(
        ptr[slots].astype(np.int64), (ptr[slots + 1] - ptr[slots]).astype(np.int64)
    )
