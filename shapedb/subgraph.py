"""Neighbourhood subgraphs N(v, K) of every node, and their Eq. 1 features, vectorised.

The paper's substructure matching (section 3.3, Algorithm 1) compares the induced
subgraphs ``G[N(v, K)]``, ``N(v, K)`` the nodes within ``K`` contact edges of ``v``,
with the Eq. 1-3 kernel computed on each subgraph *alone*: its own largest ball
``r1`` normalises the radii, and the random walk runs on the induced subgraph (a
node's degree is its degree inside the subgraph).

Computing ``kernel.features(graph.subgraph(graph.neighbourhood(v, K)))`` for each of
the n nodes costs n Python-level subgraph builds. Here all n walks run at once:

* the membership matrix ``M = [(I + A)^K > 0]`` (sparse, row v = N(v, K)) is built
  with K sparse products (BFS levels);
* each nonzero ``(v, u)`` of M is one *slot*: node u seen from subgraph v. The edges
  of every induced subgraph are the slot pairs ``((v, i), (v, j))`` with ``i ~ j``,
  found by expanding each slot's neighbours and looking the pair up in M;
* one walk step is then a ``bincount`` over those slot edges, for every subgraph
  at once, and the ``n_r`` largest balls of every subgraph come from one lexsort.

Many graphs are handled as their disjoint union (:func:`neighbourhood_features_many`),
whose neighbourhoods are exactly those of each graph. Results equal the per-node
reference (:func:`neighbourhood_features_naive`) to rounding.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from shapedb.config import PartConfig, with_options
from shapedb.errors import ConfigError, InvalidShapeError
from shapedb.graph import ContactGraph

__all__ = [
    "neighbourhoods",
    "neighbourhood_features",
    "neighbourhood_features_many",
    "neighbourhood_features_naive",
    "part_config",
]

_CHUNK_NODES = 65_536  # disjoint unions are featurised this many nodes at a time


def part_config(config: PartConfig | None = None, **options: Any) -> PartConfig:
    """A :class:`PartConfig`, ``config`` (default ``PartConfig()``) with ``options`` applied.

    Raises
    ------
    ConfigError
        For an unknown option name or an out-of-range value.
    """
    options = {k: v for k, v in options.items() if v is not None}
    return with_options(PartConfig, config, options, what="part")


def _arrays(x: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """(radii (n,), edges (m, 2)) of a ContactGraph, a Decomposition or a pair."""
    if isinstance(x, ContactGraph):
        return x.radii, x.edges.astype(np.int64)
    g = getattr(x, "graph", None)
    if isinstance(g, ContactGraph):
        return g.radii, g.edges.astype(np.int64)
    if isinstance(x, tuple) and len(x) == 2:
        r = np.asarray(x[0], dtype=np.float64).ravel()
        e = np.asarray(x[1], dtype=np.int64).reshape(-1, 2)
        if len(e) and (e.min() < 0 or e.max() >= len(r)):
            raise InvalidShapeError(f"edges refer to nodes outside 0..{len(r) - 1}")
        return r, e
    raise InvalidShapeError(
        f"expected a ContactGraph, a Decomposition or (radii, edges), got {type(x).__name__}"
    )


def _adjacency(n: int, edges: NDArray[np.int64]) -> sp.csr_matrix:
    e = edges[edges[:, 0] != edges[:, 1]]
    rows = np.concatenate([e[:, 0], e[:, 1]])
    cols = np.concatenate([e[:, 1], e[:, 0]])
    a = sp.csr_matrix((np.ones(len(rows), np.float32), (rows, cols)), shape=(n, n))
    a.sum_duplicates()
    a.data[:] = 1.0
    a.sort_indices()
    return a


def _membership(a: sp.csr_matrix, hops: int) -> sp.csr_matrix:
    n = a.shape[0]
    step = (a + sp.identity(n, dtype=np.float32, format="csr")).tocsr()
    m = sp.identity(n, dtype=np.float32, format="csr")
    for _ in range(int(hops)):
        nxt = (m @ step).tocsr()
        nxt.data[:] = 1.0
        if nxt.nnz == m.nnz:  # every neighbourhood is a whole component already
            break
        m = nxt
    m.sort_indices()
    return m


def neighbourhoods(x: Any, hops: int = 2) -> sp.csr_matrix:
    """Membership matrix of every neighbourhood N(v, K).

    Parameters
    ----------
    x : ContactGraph, Decomposition or (radii (n,), edges (m, 2))
        The graph.
    hops : int
        The range K.

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix, float32
        Entry (v, u) is 1 when u is within ``hops`` edges of v; indices sorted.
    """
    r, e = _arrays(x)
    if hops < 0:
        raise ConfigError(f"hops must be >= 0, got {hops}")
    return _membership(_adjacency(len(r), e), hops)


def _ranges(starts: NDArray[np.int64], lengths: NDArray[np.int64]) -> NDArray[np.int64]:
    """Concatenation of ``arange(s, s + l)`` over (s, l) pairs, without a Python loop."""
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    shift = starts - np.cumsum(lengths) + lengths
    return np.repeat(shift, lengths) + np.arange(total, dtype=np.int64)


def _features(
    radii: NDArray[np.float64], edges: NDArray[np.int64], cfg: PartConfig
) -> NDArray[np.float64]:
    n = len(radii)
    out = np.zeros((n, cfg.dim))
    if n == 0:
        return out
    if not np.all(np.isfinite(radii)) or radii.min() <= 0:
        raise InvalidShapeError("radii must be finite and > 0")
    a = _adjacency(n, edges)
    m = _membership(a, cfg.hops)
    ptr, cols = m.indptr.astype(np.int64), m.indices.astype(np.int64)
    nnz = len(cols)
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(ptr))
    # slot edges: slot (v, i) -> slot (v, j) for each neighbour j of i that is in N(v, K)
    aptr, aidx = a.indptr.astype(np.int64), a.indices.astype(np.int64)
    deg = np.diff(aptr)
    src = np.repeat(np.arange(nnz, dtype=np.int64), deg[cols])
    j = aidx[_ranges(aptr[cols], deg[cols])]
    key = rows[src] * n + j
    slot_keys = rows * n + cols  # ascending: CSR rows, sorted indices
    pos = np.minimum(np.searchsorted(slot_keys, key), nnz - 1)
    ok = slot_keys[pos] == key
    src, dst = src[ok], pos[ok]
    sub_deg = np.bincount(src, minlength=nnz).astype(np.float64)
    isolated = sub_deg == 0
    inv = np.divide(1.0, sub_deg, out=np.zeros(nnz), where=~isolated)
    # Eq. 1 on every subgraph at once
    r = radii[cols]
    r1 = np.maximum.reduceat(r, ptr[:-1])
    p0 = r / r1[rows]
    # one walk step of every subgraph is one sparse mat-vec over the slots
    step = sp.csr_matrix((inv[src], (dst, src)), shape=(nnz, nnz))
    keep_mass = np.where(isolated, 1.0, 0.0)
    p = p0.copy()
    acc = np.zeros(nnz)
    wk = 1.0
    for _ in range(cfg.t):
        p = step @ p + keep_mass * p
        wk *= cfg.w
        acc += wk * p
    order = np.lexsort((cols, -r, rows))  # per subgraph: decreasing radius, ties by node
    rank = np.arange(nnz) - ptr[rows[order]]
    keep = rank < cfg.n_r
    o, k = order[keep], rank[keep]
    out[rows[o], k] = p0[o]
    out[rows[o], cfg.n_r + k] = acc[o] / cfg.t
    return out


def neighbourhood_features(
    x: Any, config: PartConfig | None = None, **options: Any
) -> NDArray[np.float64]:
    """Eq. 1 features of the neighbourhood subgraph G[N(v, K)] of every node v.

    Parameters
    ----------
    x : ContactGraph, Decomposition or (radii (n,), edges (m, 2))
        The graph.
    config : PartConfig, optional
        ``hops`` (K), ``n_r`` and the kernel parameters; ``**options`` override fields.

    Returns
    -------
    (n, 2 * n_r) float64
        Row v equals ``kernel.features(graph.subgraph(graph.neighbourhood(v, K)),
        config.kernel)``.
    """
    cfg = part_config(config, **options)
    r, e = _arrays(x)
    return _features(r, e, cfg)


def neighbourhood_features_many(
    graphs: Iterable[Any], config: PartConfig | None = None, **options: Any
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """:func:`neighbourhood_features` of many graphs, computed on their disjoint unions.

    Parameters
    ----------
    graphs : iterable of ContactGraph, Decomposition or (radii, edges)
        The graphs.
    config : PartConfig, optional

    Returns
    -------
    features : (N, 2 * n_r) float64
        Rows of graph g are ``features[offsets[g]:offsets[g + 1]]``.
    offsets : (G + 1,) int64
        Node offsets of the graphs.
    """
    cfg = part_config(config, **options)
    arrays = [_arrays(g) for g in graphs]
    sizes = np.array([len(r) for r, _ in arrays], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    out = np.zeros((int(offsets[-1]), cfg.dim))
    start = 0
    while start < len(arrays):
        stop = start + 1
        while stop < len(arrays) and offsets[stop + 1] - offsets[start] <= _CHUNK_NODES:
            stop += 1
        base = offsets[start]
        r = np.concatenate([arrays[g][0] for g in range(start, stop)])
        e = np.concatenate(
            [arrays[g][1] + (offsets[g] - base) for g in range(start, stop)]
        ).reshape(-1, 2)
        out[base : offsets[stop]] = _features(r, e, cfg)
        start = stop
    return out, offsets


def neighbourhood_features_naive(
    graph: ContactGraph, config: PartConfig | None = None, *, nodes: Sequence[int] | None = None
) -> NDArray[np.float64]:
    """Reference: ``kernel.features`` of ``graph.subgraph(graph.neighbourhood(v, K))``.

    Parameters
    ----------
    graph : ContactGraph
    config : PartConfig, optional
    nodes : sequence of int, optional
        Only these nodes (default: all).

    Returns
    -------
    (len(nodes), 2 * n_r) float64
    """
    from shapedb.kernel import features

    cfg = part_config(config)
    vs = range(graph.n_nodes) if nodes is None else nodes
    rows = [features(graph.subgraph(graph.neighbourhood(int(v), cfg.hops)), cfg.kernel) for v in vs]
    return np.stack(rows) if rows else np.zeros((0, cfg.dim))


def node_sets(x: Any, nodes: ArrayLike, hops: int = 2) -> list[NDArray[np.int64]]:
    """N(v, K) of each node v in ``nodes``: a list of sorted int64 arrays."""
    r, e = _arrays(x)
    a = _adjacency(len(r), e)
    out = []
    for v in np.asarray(nodes, dtype=np.int64).ravel():
        if not 0 <= v < len(r):
            raise InvalidShapeError(f"node {v} is not in a graph of {len(r)} nodes")
        seen = np.zeros(len(r), bool)
        seen[v] = True
        frontier = np.array([v])
        for _ in range(int(hops)):
            nb = a.indices[
                _ranges(
                    a.indptr[frontier].astype(np.int64),
                    np.diff(a.indptr)[frontier].astype(np.int64),
                )
            ]
            nb = np.unique(nb[~seen[nb]])
            if not len(nb):
                break
            seen[nb] = True
            frontier = nb
        out.append(np.flatnonzero(seen))
    return out
