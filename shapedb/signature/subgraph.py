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

**Blocks beyond Eq. 1** (:class:`PartConfig` ``size``, ``centre``). Eq. 1 on a
subgraph alone is blind to scale: a one-node neighbourhood (a lone ball, e.g. a
single ball filling a hole of a complement) always has ``p0 = [1]`` and a constant
walk, so every lone ball would score 1.0 against every other. The part vector is
therefore ``[Eq. 1 (2 n_r) | size block (n_r) | centre block (2)]``:

* size block (``size > 0``, default 4): ``r_i / R`` of the part's n_r largest balls,
  R the largest ball of the *whole shape*, i.e. the paper's node attribute r/r1
  with the shape's r1; weights ``size * la^i``. Two lone balls now differ by
  ``size * la * |r / R - r' / R'|`` (plus the centre block);
* centre block (``centre > 0``, default 8): ``[r_v / r1, r_v / R]`` of the centre
  node v (r1 the part's largest ball), weight ``centre``: Eq. 1 is permutation
  invariant, so without it N(v, K) does not say which of its balls it is centred
  on. A whole-model part has no centre and uses its largest ball.

The weights were chosen on a validation subset of ``bench.parts`` (see
:class:`PartConfig`; measured in ``docs/results.md``, "Part search and matching").

A part identical to another *relative to its shape* (same balls over the same R)
still has the same vector and scores 1.0; a copy of a subgraph embedded in a shape
with a larger largest ball does not (its balls are smaller relative to that shape).
``size = centre = 0`` is the paper's vector alone (part indexes built before these
fields are read so). :func:`part_dim` and :func:`part_weights` give the layout.

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

from shapedb.config.part import PartConfig
from shapedb.errors import ConfigError, InvalidShapeError
from shapedb.mdbd.graph import ContactGraph

__all__ = [
    "concat_aranges",
    "graph_arrays",
    "part_dim",
    "part_weights",
    "part_vector",
    "part_graph",
    "neighbourhoods",
    "neighbourhood_features",
    "neighbourhood_features_many",
    "neighbourhood_features_naive",
    "part_config",
]

_CHUNK_NODES = 65_536  # disjoint unions are featurised this many nodes at a time
#: Slot-table entries (sum of n_g^2, int32) of one featurised union: 16 MB (2^22 was as fast
#: as 2^24 on the real records, at half the peak memory); a graph with
#: more falls back to a binary search over the slots.
_TABLE_ENTRIES = 2**22


def part_config(config: PartConfig | None = None, **options: Any) -> PartConfig:
    """A :class:`PartConfig`, ``config`` (default ``PartConfig()``) with ``options`` applied.

    Options are :class:`PartConfig` fields or fields of its kernel (``n_r``, ``la``...,
    :meth:`PartConfig.with_options`); None values are ignored.

    Raises
    ------
    ConfigError
        For an unknown option name or an out-of-range value.
    """
    options = {k: v for k, v in options.items() if v is not None}
    cfg = config if config is not None else PartConfig()
    if not isinstance(cfg, PartConfig):
        raise ConfigError(f"config must be a PartConfig, got {type(cfg).__name__}")
    return cfg.with_options(**options)


def part_dim(cfg: PartConfig) -> int:
    """Length of a part vector: 2 n_r, plus n_r with the size block, plus 2 with the centre."""
    return (
        2 * cfg.kernel.n_r + (cfg.kernel.n_r if cfg.size > 0 else 0) + (2 if cfg.centre > 0 else 0)
    )


def part_weights(cfg: PartConfig) -> NDArray[np.float64]:
    """(part_dim,) weights of the part distance (Eq. 2 extended): weighted L1 is the distance.

    ``[la^1..la^nr, lb^1..lb^nr]`` (Eq. 2), then ``size * la^1..la^nr`` and
    ``[centre, centre]`` when those blocks are on.
    """
    i = np.arange(1, cfg.kernel.n_r + 1, dtype=np.float64)
    blocks = [cfg.kernel.la**i, cfg.kernel.lb**i]
    if cfg.size > 0:
        blocks.append(cfg.size * cfg.kernel.la**i)
    if cfg.centre > 0:
        blocks.append(np.full(2, float(cfg.centre)))
    return np.concatenate(blocks)


def part_graph(decomposition: Any, config: PartConfig | None = None) -> ContactGraph:
    """The contact graph part matching uses: contacts found again at the part tolerance.

    Parameters
    ----------
    decomposition : Decomposition
        Its balls (``centers``, ``radii``) and grid ``spacing``; its own contact
        graph (``decomposition.graph``) when ``config.contact_tol_cells`` is 0.
    config : PartConfig, optional

    Returns
    -------
    ContactGraph
        Balls closer than ``config.contact_tol_cells`` grid cells are joined.
    """
    from shapedb.mdbd.graph import contact_edges

    cfg = part_config(config)
    if cfg.contact_tol_cells <= 0:
        graph: ContactGraph = decomposition.graph
        return graph
    tol = cfg.contact_tol_cells * float(decomposition.spacing)
    edges = contact_edges(decomposition.centers, decomposition.radii, tol)
    return ContactGraph(decomposition.centers, decomposition.radii, edges)


def part_vector(
    graph: ContactGraph,
    nodes: ArrayLike | None = None,
    centre: int | None = None,
    config: PartConfig | None = None,
) -> NDArray[np.float64]:
    """Reference part vector of ``graph.subgraph(nodes)`` (Eq. 1 plus the extra blocks).

    Parameters
    ----------
    graph : ContactGraph
        The whole shape (its largest ball is R).
    nodes : (m,) int, optional
        The part's nodes (default: all, the whole model as the part).
    centre : int, optional
        Centre node v (default: the part's largest ball).
    config : PartConfig, optional

    Returns
    -------
    (part_dim,) float64
    """
    from shapedb.signature.kernel import features

    cfg = part_config(config)
    idx = (
        np.arange(graph.n_nodes, dtype=np.int64)
        if nodes is None
        else np.asarray(nodes, np.int64).ravel()
    )
    if not len(idx):
        raise InvalidShapeError("a part needs at least one node")
    sub = graph.subgraph(idx)
    blocks = [features(sub, cfg.kernel)]
    big = float(np.max(graph.radii))
    r = np.asarray(graph.radii, np.float64)[idx]
    if cfg.size > 0:
        top = np.zeros(cfg.kernel.n_r)
        srt = np.sort(r)[::-1][: cfg.kernel.n_r]
        top[: len(srt)] = srt / big
        blocks.append(top)
    if cfg.centre > 0:
        rv = float(r.max() if centre is None else graph.radii[int(centre)])
        blocks.append(np.array([rv / r.max(), rv / big]))
    return np.concatenate(blocks)


def graph_arrays(x: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
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
    r, e = graph_arrays(x)
    if hops < 0:
        raise ConfigError(f"hops must be >= 0, got {hops}")
    return _membership(_adjacency(len(r), e), hops)


def concat_aranges(starts: NDArray[np.int64], lengths: NDArray[np.int64]) -> NDArray[np.int64]:
    """Concatenation of ``arange(s, s + l)`` over (s, l) pairs, without a Python loop."""
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    shift = starts - np.cumsum(lengths) + lengths
    return np.repeat(shift, lengths) + np.arange(total, dtype=np.int64)


def _slot_edges(
    a: sp.csr_matrix, m: sp.csr_matrix, shape_of: NDArray[np.int64] | None
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Edges ``(src, dst)`` between slots of every induced subgraph, src ascending.

    Slot ``s = (v, i)`` (a nonzero of ``m``) joins slot ``(v, j)`` for each neighbour j of
    i in N(v, K); within one src the dsts follow j ascending. ``shape_of`` (n,) numbers
    each node's graph in a disjoint union: slots are then found in a dense per-graph
    table (a gather) rather than by a binary search over all slots.
    """
    n = a.shape[0]
    ptr, cols = m.indptr.astype(np.int64), m.indices.astype(np.int64)
    nnz = len(cols)
    aptr = a.indptr.astype(np.int64)
    deg = np.diff(aptr)[cols]
    src = np.repeat(np.arange(nnz, dtype=np.int32 if nnz < 2**31 else np.int64), deg)
    j_at = concat_aranges(aptr[cols], deg)
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(ptr))
    if shape_of is not None:
        start = np.r_[0, np.flatnonzero(np.diff(shape_of)) + 1]
        size = np.diff(np.r_[start, n])
        table_at = np.r_[0, np.cumsum(size * size)]
        g = np.repeat(np.arange(len(start)), size)
        loc = np.arange(n) - start[g]
        table = np.full(int(table_at[-1]), -1, np.int32)  # nnz <= table size < 2^31
        row_base = table_at[g] + loc * size[g]
        table[row_base[rows] + loc[cols]] = np.arange(nnz, dtype=np.int32)
        key = np.repeat(row_base[rows], deg) + loc[a.indices][j_at]
        dst = table[key]
        ok = dst >= 0
        return src[ok].astype(np.int64), dst[ok]
    j = a.indices.astype(np.int64)[j_at]
    key = np.repeat(rows, deg) * n + j
    slot_keys = rows * n + cols  # ascending: CSR rows, sorted indices
    pos = np.minimum(np.searchsorted(slot_keys, key), nnz - 1)
    ok = slot_keys[pos] == key
    return src[ok].astype(np.int64), pos[ok]


def _features(
    radii: NDArray[np.float64],
    edges: NDArray[np.int64],
    cfg: PartConfig,
    big: NDArray[np.float64] | None = None,
    shape_of: NDArray[np.int64] | None = None,
) -> NDArray[np.float64]:
    """Part vectors of every node; ``big`` (n,) is R of each node's shape (default max r);
    ``shape_of`` (n,) non-decreasing graph numbers of a disjoint union (:func:`_slot_edges`)."""
    n = len(radii)
    out = np.zeros((n, part_dim(cfg)))
    if n == 0:
        return out
    if not np.all(np.isfinite(radii)) or radii.min() <= 0:
        raise InvalidShapeError("radii must be finite and > 0")
    if big is None:
        big = np.full(n, radii.max())
    a = _adjacency(n, edges)
    m = _membership(a, cfg.hops)
    ptr, cols = m.indptr.astype(np.int64), m.indices.astype(np.int64)
    nnz = len(cols)
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(ptr))
    src, dst = _slot_edges(a, m, shape_of)
    sub_deg = np.bincount(src, minlength=nnz).astype(np.float64)
    isolated = sub_deg == 0
    inv = np.divide(1.0, sub_deg, out=np.zeros(nnz), where=~isolated)
    # Eq. 1 on every subgraph at once
    r = radii[cols]
    r1 = np.maximum.reduceat(r, ptr[:-1])
    p0 = r / r1[rows]
    # one walk step of every subgraph is one sparse mat-vec over the slots; src is
    # ascending, so the step is built as CSC directly (column src holds its dsts)
    col_ptr = np.r_[0, np.cumsum(sub_deg.astype(np.int64))]
    step = sp.csc_matrix((inv[src], dst, col_ptr), shape=(nnz, nnz))
    keep_mass = np.where(isolated, 1.0, 0.0)
    p = p0.copy()
    acc = np.zeros(nnz)
    wk = 1.0
    for _ in range(cfg.kernel.t):
        p = step @ p + keep_mass * p
        wk *= cfg.kernel.w
        acc += wk * p
    # per subgraph: decreasing radius, ties by node (the node's rank in that order)
    node_rank = np.empty(n, np.int64)
    node_rank[np.lexsort((np.arange(n), -radii))] = np.arange(n)
    order = np.argsort(rows * n + node_rank[cols])
    rank = np.arange(nnz) - ptr[rows[order]]
    keep = rank < cfg.kernel.n_r
    o, k = order[keep], rank[keep]
    out[rows[o], k] = p0[o]
    out[rows[o], cfg.kernel.n_r + k] = acc[o] / cfg.kernel.t
    col = 2 * cfg.kernel.n_r
    if cfg.size > 0:  # the part's largest balls relative to the whole shape
        out[rows[o], col + k] = r[o] / big[rows[o]]
        col += cfg.kernel.n_r
    if cfg.centre > 0:
        out[:, col] = radii / r1
        out[:, col + 1] = radii / big
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
    (n, part_dim) float64
        Row v equals ``part_vector(graph, graph.neighbourhood(v, K), v, config)``:
        ``kernel.features`` of the subgraph, then the size and centre blocks.
    """
    cfg = part_config(config, **options)
    r, e = graph_arrays(x)
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
    features : (N, part_dim) float64
        Rows of graph g are ``features[offsets[g]:offsets[g + 1]]``.
    offsets : (G + 1,) int64
        Node offsets of the graphs.
    """
    cfg = part_config(config, **options)
    arrays = [graph_arrays(g) for g in graphs]
    sizes = np.array([len(r) for r, _ in arrays], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    out = np.zeros((int(offsets[-1]), part_dim(cfg)))
    square = np.concatenate([[0], np.cumsum(sizes * sizes)])
    start = 0
    while start < len(arrays):
        stop = start + 1
        while (
            stop < len(arrays)
            and offsets[stop + 1] - offsets[start] <= _CHUNK_NODES
            and square[stop + 1] - square[start] <= _TABLE_ENTRIES
        ):
            stop += 1
        base = offsets[start]
        r = np.concatenate([arrays[g][0] for g in range(start, stop)])
        e = np.concatenate(
            [arrays[g][1] + (offsets[g] - base) for g in range(start, stop)]
        ).reshape(-1, 2)
        big = np.repeat(
            [arrays[g][0].max() if len(arrays[g][0]) else 1.0 for g in range(start, stop)],
            sizes[start:stop],
        )
        dense = square[stop] - square[start] <= _TABLE_ENTRIES
        shape_of = np.repeat(np.arange(stop - start), sizes[start:stop]) if dense else None
        out[base : offsets[stop]] = _features(r, e, cfg, big, shape_of)
        start = stop
    return out, offsets


def neighbourhood_features_naive(
    graph: ContactGraph, config: PartConfig | None = None, *, nodes: Sequence[int] | None = None
) -> NDArray[np.float64]:
    """Reference: :func:`part_vector` of ``graph.neighbourhood(v, K)``, node by node.

    Parameters
    ----------
    graph : ContactGraph
    config : PartConfig, optional
    nodes : sequence of int, optional
        Only these nodes (default: all).

    Returns
    -------
    (len(nodes), part_dim) float64
    """
    cfg = part_config(config)
    vs = range(graph.n_nodes) if nodes is None else nodes
    rows = [part_vector(graph, graph.neighbourhood(int(v), cfg.hops), int(v), cfg) for v in vs]
    return np.stack(rows) if rows else np.zeros((0, part_dim(cfg)))


def node_sets(x: Any, nodes: ArrayLike, hops: int = 2) -> list[NDArray[np.int64]]:
    """N(v, K) of each node v in ``nodes``: a list of sorted int64 arrays."""
    r, e = graph_arrays(x)
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
                concat_aranges(
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
