"""The contact graph of a ball decomposition (paper, section 2.2).

Nodes are balls, ordered by decreasing radius; an edge joins two balls that touch.
Balls of a computed MDBD are tangent only up to the grid's accuracy, so "touch"
means a gap ``|ci - cj| - ri - rj`` of at most ``tol``. shapedb ties ``tol`` to
the grid, ``tol = MDBDConfig.contact_tol_cells * spacing`` (one cell by
default), which is scale invariant; the paper used an absolute 0.05 on models
normalised to unit size, i.e. several cells at its resolutions, which also
connects balls that are merely close.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from shapedb.errors import InvalidShapeError, NotFoundError

if TYPE_CHECKING:
    import networkx

__all__ = ["ContactGraph", "contact_edges"]

_DENSE_LIMIT = 4096  # up to this many balls, all pairs are tested in dense blocks


def _balls(centers: ArrayLike, radii: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    c = np.asarray(centers, dtype=np.float64)
    r = np.asarray(radii, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 3:
        raise InvalidShapeError(f"centers must have shape (n, 3), got {c.shape}")
    if r.shape != (len(c),):
        raise InvalidShapeError(f"radii must have shape ({len(c)},), got {r.shape}")
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(r))):
        raise InvalidShapeError("centers and radii must be finite")
    return c, r


def contact_edges(centers: ArrayLike, radii: ArrayLike, tol: float) -> NDArray[np.int32]:
    """Pairs of balls whose gap ``|ci - cj| - ri - rj`` is at most ``tol``.

    Parameters
    ----------
    centers : (n, 3) float
        Ball centres, model units.
    radii : (n,) float
        Ball radii, model units.
    tol : float
        Largest gap that still counts as contact, model units (>= 0).

    Returns
    -------
    (m, 2) int32
        Edges with i < j, rows sorted lexicographically.
    """
    c, r = _balls(centers, radii)
    n = len(r)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int32)
    parts: list[NDArray[np.int64]] = []
    if n <= _DENSE_LIMIT:
        step = max(1, (1 << 22) // n)
        for s in range(0, n, step):
            d = np.sqrt(((c[s : s + step, None, :] - c[None, :, :]) ** 2).sum(axis=2))
            gap = d - r[s : s + step, None] - r[None, :]
            i, j = np.nonzero(gap <= tol)
            i = i + s
            keep = i < j
            parts.append(np.stack([i[keep], j[keep]], axis=1))
    else:
        tree = cKDTree(c)
        rmax = float(r.max())
        for a, nbrs in enumerate(tree.query_ball_point(c, r + rmax + tol)):
            b = np.asarray(nbrs, dtype=np.int64)
            b = b[b > a]
            gap = np.sqrt(((c[b] - c[a]) ** 2).sum(axis=1)) - r[a] - r[b]
            b = b[gap <= tol]
            parts.append(np.stack([np.full(len(b), a), b], axis=1))
    e = np.concatenate(parts) if parts else np.zeros((0, 2), dtype=np.int64)
    e = e[np.lexsort((e[:, 1], e[:, 0]))]
    return e.astype(np.int32)


class ContactGraph:
    """Undirected contact graph of balls.

    Parameters
    ----------
    centers : (n, 3) float
        Ball centres, model units.
    radii : (n,) float
        Ball radii; node 0 should be the largest ball (MDBD order).
    edges : (m, 2) int
        Pairs of touching balls; normalised to i < j, sorted, duplicates and
        self-loops dropped.
    ids : (n,) int, optional
        Original node numbers (set by :meth:`subgraph`); defaults to 0..n-1.
    """

    def __init__(
        self,
        centers: ArrayLike,
        radii: ArrayLike,
        edges: ArrayLike,
        *,
        ids: ArrayLike | None = None,
    ) -> None:
        self.centers, self.radii = _balls(centers, radii)
        n = len(self.radii)
        e = np.asarray(edges, dtype=np.int64)
        if e.size == 0:
            e = np.zeros((0, 2), dtype=np.int64)
        if e.ndim != 2 or e.shape[1] != 2:
            raise InvalidShapeError(f"edges must have shape (m, 2), got {np.shape(edges)}")
        if len(e) and (e.min() < 0 or e.max() >= n):
            raise InvalidShapeError(f"edges refer to nodes outside 0..{n - 1}")
        e = np.sort(e, axis=1)
        e = np.unique(e[e[:, 0] != e[:, 1]], axis=0)
        self.edges: NDArray[np.int32] = e.astype(np.int32).reshape(-1, 2)
        self.ids = np.arange(n) if ids is None else np.asarray(ids, dtype=np.int64)
        if self.ids.shape != (n,):
            raise InvalidShapeError(f"ids must have shape ({n},), got {self.ids.shape}")

    @property
    def n_nodes(self) -> int:
        """Number of nodes n."""
        return int(len(self.radii))

    @property
    def n_edges(self) -> int:
        """Number of (undirected) edges m."""
        return int(len(self.edges))

    def __len__(self) -> int:
        return self.n_nodes

    def __repr__(self) -> str:
        return f"<ContactGraph n_nodes={self.n_nodes} n_edges={self.n_edges}>"

    @cached_property
    def degrees(self) -> NDArray[np.int64]:
        """(n,) int: number of balls each ball touches."""
        return np.bincount(self.edges.ravel(), minlength=self.n_nodes).astype(np.int64)

    def adjacency(self) -> sp.csr_matrix:
        """(n, n) symmetric 0/1 adjacency matrix, CSR."""
        return self._adjacency.copy()

    @cached_property
    def _adjacency(self) -> sp.csr_matrix:
        n, e = self.n_nodes, self.edges
        rows = np.concatenate([e[:, 0], e[:, 1]])
        cols = np.concatenate([e[:, 1], e[:, 0]])
        a = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
        a.sort_indices()
        return a

    def transition(self) -> sp.csr_matrix:
        """(n, n) column-stochastic random-walk matrix, CSR.

        Entry (i, j) is 1/deg(j) for each edge (i, j): the mass on node j spreads
        equally to its neighbours (the paper's edge weight 1/deg), so ``A @ p``
        conserves the total of ``p``. An isolated node has no neighbour to spread
        to and keeps its mass (entry (j, j) = 1), so every column sums to one.
        """
        return self._transition.copy()

    @cached_property
    def _transition(self) -> sp.csr_matrix:
        deg = self.degrees.astype(np.float64)
        a = self._adjacency @ sp.diags(np.divide(1.0, deg, out=np.zeros_like(deg), where=deg > 0))
        a = a + sp.diags((deg == 0).astype(np.float64))
        a = sp.csr_matrix(a)
        a.eliminate_zeros()
        a.sort_indices()
        return a

    def node_attributes(self) -> NDArray[np.float64]:
        """(n, 4) float: [centre x, y, z, r / r1], r1 the largest radius (paper 3.1)."""
        r1 = float(self.radii.max()) if self.n_nodes else 1.0
        return np.column_stack([self.centers, self.radii / r1])

    def neighbourhood(self, v: int, hops: int) -> NDArray[np.int64]:
        """Nodes within ``hops`` edges of node ``v``, ``v`` included, sorted: N(v, K).

        Raises
        ------
        NotFoundError
            If ``v`` is not a node.
        """
        if not 0 <= int(v) < self.n_nodes:
            raise NotFoundError(f"node {v} is not in a graph of {self.n_nodes} nodes")
        if hops < 0:
            raise ValueError(f"hops must be >= 0, got {hops}")
        a = self._adjacency
        seen = np.zeros(self.n_nodes, dtype=bool)
        seen[int(v)] = True
        frontier = np.array([int(v)])
        for _ in range(int(hops)):
            if not len(frontier):
                break
            nbrs = np.concatenate([a.indices[a.indptr[u] : a.indptr[u + 1]] for u in frontier])
            nbrs = np.unique(nbrs[~seen[nbrs]])
            seen[nbrs] = True
            frontier = nbrs
        return np.flatnonzero(seen)

    def subgraph(self, nodes: Sequence[int] | NDArray[np.integer]) -> ContactGraph:
        """Induced subgraph G[S] on ``nodes``, kept in increasing node (radius) order.

        The result's ``ids`` hold the original node numbers.
        """
        s = np.unique(np.asarray(nodes, dtype=np.int64))
        if len(s) and (s[0] < 0 or s[-1] >= self.n_nodes):
            raise NotFoundError(f"subgraph nodes must lie in 0..{self.n_nodes - 1}")
        new = np.full(self.n_nodes, -1, dtype=np.int64)
        new[s] = np.arange(len(s))
        e = new[self.edges]
        e = e[(e >= 0).all(axis=1)]
        return ContactGraph(self.centers[s], self.radii[s], e, ids=self.ids[s])

    def to_networkx(self) -> networkx.Graph:
        """A ``networkx.Graph`` with node attributes ``center`` (3-tuple), ``radius``,
        ``r_norm`` (r / r1) and ``id``, and edge attributes ``weight`` (distance between
        the centres, model units) and ``gap`` (|ci - cj| - ri - rj)."""
        import networkx as nx

        g = nx.Graph()
        attrs = self.node_attributes()
        for i in range(self.n_nodes):
            g.add_node(
                i,
                center=tuple(float(x) for x in self.centers[i]),
                radius=float(self.radii[i]),
                r_norm=float(attrs[i, 3]),
                id=int(self.ids[i]),
            )
        if self.n_edges:
            u, v = self.edges[:, 0], self.edges[:, 1]
            dist = np.linalg.norm(self.centers[u] - self.centers[v], axis=1)
            gap = dist - self.radii[u] - self.radii[v]
            g.add_edges_from(
                (int(a), int(b), {"weight": float(w), "gap": float(q)})
                for a, b, w, q in zip(u.tolist(), v.tolist(), dist, gap, strict=True)
            )
        return g
