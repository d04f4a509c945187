"""Substructure matching: the paper's Algorithm 1, and part search over the whole store.

A *part* is a neighbourhood subgraph ``G[N(v, K)]`` of a contact graph (paper 3.3),
compared with the Eq. 1-3 kernel computed on the subgraph alone
(:mod:`shapedb.signature.subgraph`; K = 2, n_r = 10 by default, :class:`PartConfig`).

* **Pairwise** (Algorithm 1): ``match(db, a, b)`` scores every pair (v, u) of nodes of
  ``a`` and ``b`` by ``k(G1[N(v, K)], G2[N(u, K)])`` and returns the ``top`` pairs.
  With ``node=`` or ``point=`` only that node of ``a`` is the query.
* **Corpus** (``b=None``): ``match(db, a, node=v)`` returns the ``k`` stored shapes
  holding the neighbourhoods most like ``G_a[N(v, K)]`` (best node per shape, best
  first), through :mod:`query.parts.index` (faiss candidates, exact re-rank). Without
  ``node``/``point`` the whole of ``a`` (a small model standing for the part) is the
  query. ``complement=True`` decomposes the query's complement in its bounding box
  (:class:`shapedb.geometry.complement.Complement`), for holes and slots; restrict the corpus
  to stored complements with ``where``.
* **Non-maximum suppression** (``overlap``, default 0.0, on): neighbouring centres
  have nearly the same neighbourhood, so the best pairs of Algorithm 1 are often one
  region shifted by a node. Pairs are taken greedily in distance order, and a pair is
  dropped when, against a pair already taken, its node sets overlap by more than
  ``overlap`` (Jaccard |A & B| / |A | B|) on *both* sides (query and target); with
  ``node=``/``point=`` the query side is fixed, so the target sets must differ. The
  default 0.0 asks for disjoint node sets; ``overlap=None`` turns suppression off
  (the paper's plain top-m). Corpus search applies the same rule among the matches
  of one shape when ``per_shape > 1``.
* **Part vector**: Eq. 1 of the subgraph plus the size block (balls relative to the
  whole shape's largest, ``PartConfig.size``) and the centre block (the centre ball,
  ``PartConfig.centre``), so that lone balls of different sizes no longer score 1.0
  against each other (:mod:`shapedb.signature.subgraph`).
* **Back to geometry**: :func:`part_geometry` maps a match's nodes to their balls and
  to the mesh faces or points that lie in them.

``a`` and ``b`` may be stored ids or names, paths, :class:`Geometry`,
:class:`Decomposition`, :class:`ShapeRecord` or :class:`ContactGraph`.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from query.search.catalog import catalog
from shapedb.config.part import PartConfig
from shapedb.errors import ConfigError, InvalidShapeError, NotFoundError, QueryError
from shapedb.mdbd.graph import ContactGraph
from shapedb.results import PartMatch  # defined there, re-exported here
from shapedb.signature.subgraph import (
    neighbourhood_features,
    neighbourhoods,
    node_sets,
    part_config,
    part_graph,
    part_vector,
    part_weights,
)

if TYPE_CHECKING:
    from shapedb.store.handle import StoreHandle

__all__ = [
    "PartMatch",
    "PartGeometry",
    "Model",
    "match",
    "match_pairs",
    "match_brute_force",
    "resolve",
    "nearest_ball",
    "part_feature",
    "part_geometry",
]

log = logging.getLogger(__name__)

_PAIR_BLOCK = 1 << 22  # entries of the (n1, n2) distance matrix computed at once
_NMS_POOL = 32  # candidate pairs per wanted pair before suppression (widened x4 when short)


@dataclass(frozen=True, eq=False)
class Model:
    """A resolved query or target: its graph and, when stored, who it is.

    Attributes
    ----------
    graph : ContactGraph
    decomposition : Decomposition or None
    geometry : Geometry or None
        The source geometry when known (for pictures and :func:`part_geometry`).
    id, name, label : stored identity, or None
    """

    graph: ContactGraph
    decomposition: Any = None
    geometry: Any = None
    id: int | None = None
    name: str | None = None
    label: str | None = None


@dataclass(frozen=True, eq=False)
class PartGeometry:
    """A part mapped back to geometry.

    Attributes
    ----------
    nodes : (k,) int64
        Ball numbers.
    centers : (k, 3) float64
    radii : (k,) float64
    faces : (f,) int64 or None
        Mesh faces whose centroid lies in one of the balls (nearest ball, within
        ``tol`` of its sphere); None without a mesh.
    points : (p,) int64 or None
        Point-cloud points (or mesh vertices) lying in the balls, likewise.
    """

    nodes: NDArray[np.int64]
    centers: NDArray[np.float64]
    radii: NDArray[np.float64]
    faces: NDArray[np.int64] | None = None
    points: NDArray[np.int64] | None = None


# ------------------------------------------------------------------ resolving inputs
def resolve(
    db: StoreHandle | None,
    x: Any,
    *,
    complement: bool = False,
    padding: float = 0.0,
    part: PartConfig | None = None,
) -> Model:
    """A :class:`Model` from a stored id/name, path, Geometry, Decomposition,
    ShapeRecord or ContactGraph; decomposed with the store's configuration (or the
    default one when ``db`` is None). With ``part``, the model's graph is the part
    graph (:func:`shapedb.signature.subgraph.part_graph`; a ContactGraph is taken as it is)."""
    model = _resolve(db, x, complement=complement, padding=padding)
    if part is None or model.decomposition is None:
        return model
    return replace(model, graph=part_graph(model.decomposition, part))


def _resolve(db: StoreHandle | None, x: Any, *, complement: bool, padding: float) -> Model:
    from shapedb.geometry.base import Geometry
    from shapedb.mdbd.decomposition import Decomposition, decompose
    from shapedb.store.schema import ShapeRecord

    mdbd = db.config.mdbd if db is not None else None
    if isinstance(x, bool):
        raise QueryError("a boolean is not a model", source=repr(x))
    if complement and not isinstance(x, (Geometry, str, os.PathLike)):
        raise QueryError("complement=True needs a Geometry or a path", source=type(x).__name__)
    if isinstance(x, ContactGraph):
        return Model(x)
    if isinstance(x, Decomposition):
        return Model(x.graph, x)
    if isinstance(x, ShapeRecord):
        return Model(x.decomposition.graph, x.decomposition, None, x.id, x.name, x.label)
    if isinstance(x, Geometry):
        g = _complement(x, padding) if complement else x
        d = decompose(g, config=mdbd)
        return Model(d.graph, d, g, None, getattr(x, "name", None))
    path = _as_path(x)
    if path is not None:
        import ingest  # the public API only

        geometry = ingest.load(path)
        g = _complement(geometry, padding) if complement else geometry
        d = decompose(g, config=mdbd)
        return Model(d.graph, d, g, None, path.stem)
    if isinstance(x, (int, np.integer, str)):
        if db is None:
            raise QueryError("a stored id or name needs a database", source=x)
        rec = db.get(int(x) if isinstance(x, (int, np.integer)) else x)
        return Model(rec.decomposition.graph, rec.decomposition, None, rec.id, rec.name, rec.label)
    raise QueryError(
        "unsupported model: expected a stored id or name, a path, a Geometry, a "
        "Decomposition, a ShapeRecord or a ContactGraph",
        source=type(x).__name__,
    )


def _complement(g: Any, padding: float) -> Any:
    from shapedb.geometry.complement import Complement

    return Complement(g, padding=padding)


def _as_path(x: Any) -> Path | None:
    if isinstance(x, os.PathLike):
        return Path(x)
    if isinstance(x, str):
        try:
            return Path(x) if Path(x).is_file() else None
        except (OSError, ValueError):
            return None
    return None


def nearest_ball(graph: Any, point: ArrayLike) -> int:
    """The ball nearest to ``point`` (3,): smallest ``|p - c| - r`` (inside is negative).

    Parameters
    ----------
    graph : ContactGraph or Decomposition
    point : (3,) float
    """
    c = np.asarray(graph.centers, np.float64)
    r = np.asarray(graph.radii, np.float64)
    p = np.asarray(point, np.float64).ravel()
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise QueryError("point must be 3 finite coordinates", source=repr(point))
    if not len(r):
        raise InvalidShapeError("the model has no balls", source=repr(graph))
    return int(np.argmin(np.linalg.norm(c - p, axis=1) - r))


def _query_node(model: Model, node: int | None, point: ArrayLike | None) -> int | None:
    if node is not None and point is not None:
        raise QueryError("give node or point, not both", source=f"node={node}, point={point}")
    if point is not None:
        return nearest_ball(model.graph, point)
    if node is None:
        return None
    if isinstance(node, bool) or not 0 <= int(node) < model.graph.n_nodes:
        raise NotFoundError(
            f"node is not in the query's graph of {model.graph.n_nodes} nodes", source=node
        )
    return int(node)


def part_feature(
    x: Any, node: int | None = None, config: PartConfig | None = None
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The part vector (Eq. 1 plus size/centre blocks) of a part and its node set.

    Parameters
    ----------
    x : ContactGraph or Decomposition
    node : int, optional
        Centre v; the part is G[N(v, K)]. None: the whole graph is the part.
    config : PartConfig, optional

    Returns
    -------
    feature : (part_dim,) float64
    nodes : (m,) int64
    """
    cfg = part_config(config)
    g = x if isinstance(x, ContactGraph) else x.graph
    if node is None:
        nodes = np.arange(g.n_nodes, dtype=np.int64)
        return part_vector(g, nodes, None, cfg), nodes
    nodes = g.neighbourhood(int(node), cfg.hops)
    return part_vector(g, nodes, int(node), cfg), nodes


# ------------------------------------------------------------------ Algorithm 1
def _check_overlap(overlap: float | None) -> float | None:
    if overlap is None:
        return None
    if isinstance(overlap, bool) or not 0.0 <= float(overlap) < 1.0:
        raise QueryError("overlap must be in [0, 1) or None", source=f"overlap={overlap!r}")
    return float(overlap)


def _best_pairs(
    f1w: NDArray[np.float64], f2w: NDArray[np.float64], rows: NDArray[np.int64], count: int
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """The ``count`` smallest L1 distances between rows of f1w and f2w (ties by v, u)."""
    best_v: NDArray[np.int64] = np.zeros(0, np.int64)
    best_u: NDArray[np.int64] = np.zeros(0, np.int64)
    best_d: NDArray[np.float64] = np.zeros(0)
    step = max(1, _PAIR_BLOCK // max(len(f2w) * f1w.shape[1], 1))
    for s in range(0, len(rows), step):
        d = np.abs(f1w[s : s + step, None, :] - f2w[None, :, :]).sum(axis=2)
        i, j = np.unravel_index(np.arange(d.size), d.shape)
        dd = d.ravel()
        if dd.size > count:
            thr = np.partition(dd, count - 1)[count - 1]
            keep = dd <= thr
            i, j, dd = i[keep], j[keep], dd[keep]
        best_v = np.concatenate([best_v, rows[s + i]])
        best_u = np.concatenate([best_u, j.astype(np.int64)])
        best_d = np.concatenate([best_d, dd])
        order = np.lexsort((best_u, best_v, best_d))[:count]
        best_v, best_u, best_d = best_v[order], best_u[order], best_d[order]
    return best_v, best_u, best_d


def _jaccard(members: Any, a: NDArray[np.int64], b: NDArray[np.int64]) -> NDArray[np.float64]:
    """(len(a), len(b)) Jaccard overlaps of the node sets N(a_i, K) and N(b_j, K)."""
    ma, mb = members[a], members[b]
    inter = np.asarray((ma @ mb.T).todense(), np.float64)
    sa = np.asarray(ma.sum(axis=1), np.float64).reshape(-1, 1)
    sb = np.asarray(mb.sum(axis=1), np.float64).reshape(1, -1)
    return inter / np.maximum(sa + sb - inter, 1.0)


def _suppress(
    v: NDArray[np.int64],
    u: NDArray[np.int64],
    members1: Any,
    members2: Any,
    overlap: float,
    top: int,
) -> NDArray[np.int64]:
    """Greedy NMS over pairs sorted best first: positions of the pairs kept (<= top)."""
    uv, iv = np.unique(v, return_inverse=True)
    uu, iu = np.unique(u, return_inverse=True)
    j1, j2 = _jaccard(members1, uv, uv), _jaccard(members2, uu, uu)
    kept: list[int] = []
    for p in range(len(v)):
        if kept:
            k = np.asarray(kept)
            if np.any((j1[iv[p], iv[k]] > overlap) & (j2[iu[p], iu[k]] > overlap)):
                continue
        kept.append(p)
        if len(kept) == top:
            break
    return np.asarray(kept, np.int64)


def match_pairs(
    g1: Any,
    g2: Any,
    *,
    config: PartConfig | None = None,
    top: int = 5,
    nodes1: ArrayLike | None = None,
    overlap: float | None = 0.0,
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """Algorithm 1: the ``top`` most similar neighbourhood-subgraph pairs of two graphs.

    Parameters
    ----------
    g1, g2 : ContactGraph or Decomposition
    config : PartConfig, optional
    top : int
        Pairs wanted.
    nodes1 : (q,) int, optional
        Only these nodes of ``g1`` (default: all).
    overlap : float in [0, 1) or None
        Non-maximum suppression: a pair is dropped when its node sets overlap
        (Jaccard) a better pair's by more than this on both sides. 0.0 (default):
        every two pairs kept are disjoint on at least one side. None: plain top-m.

    Returns
    -------
    v : (<= top,) int64
        Nodes of ``g1``.
    u : (<= top,) int64
        Nodes of ``g2``.
    distances : (<= top,) float64
        Part distances (Eq. 2 extended, :func:`shapedb.signature.subgraph.part_weights`),
        ascending; ties by v then u.
    """
    cfg = part_config(config)
    overlap = _check_overlap(overlap)
    top = int(top)
    if top < 1:
        raise QueryError("top must be >= 1", source=f"top={top}")
    f1 = neighbourhood_features(g1, cfg)
    f2 = neighbourhood_features(g2, cfg)
    rows = np.arange(len(f1)) if nodes1 is None else np.asarray(nodes1, np.int64).ravel()
    w = part_weights(cfg)
    f1w, f2w = f1[rows] * w, f2 * w
    if overlap is None:
        return _best_pairs(f1w, f2w, rows, top)
    members1, members2 = neighbourhoods(g1, cfg.hops), neighbourhoods(g2, cfg.hops)
    total = len(rows) * len(f2)
    count = min(total, _NMS_POOL * top)
    while True:
        v, u, d = _best_pairs(f1w, f2w, rows, count)
        kept = _suppress(v, u, members1, members2, overlap, top)
        if len(kept) == top or count >= total:
            return v[kept], u[kept], d[kept]
        count = min(total, 4 * count)


def match(
    db: StoreHandle | None,
    a: Any,
    b: Any = None,
    *,
    node: int | None = None,
    point: ArrayLike | None = None,
    hops: int = 2,
    top: int = 5,
    k: int = 10,
    config: PartConfig | None = None,
    where: str | None = None,
    per_shape: int = 1,
    complement: bool = False,
    overlap: float | None = 0.0,
) -> list[PartMatch]:
    """Substructure matching: Algorithm 1 between ``a`` and ``b``, or part search.

    Parameters
    ----------
    db : shapedb.Database or None
        The store (needed for stored ids/names and for corpus search).
    a : id, name, path, Geometry, Decomposition, ShapeRecord or ContactGraph
        The query model.
    b : same, optional
        The target model. None: search the whole store.
    node : int, optional
        Query node v (its neighbourhood N(v, K) is the part).
    point : (3,) float, optional
        A point on the query, mapped to the nearest ball.
    hops : int
        K, the neighbourhood range (overrides ``config.hops``).
    top : int
        Pairs returned by the pairwise match.
    k : int
        Shapes returned by the corpus search.
    config : PartConfig, optional
        Part kernel parameters (n_r, t, w, la, lb, lam) and the tolerance at which
        the contacts of a decomposed model are found again
        (:func:`shapedb.signature.subgraph.part_graph`; a ContactGraph is used as it is).
    where : str, optional
        SQL predicate over ``shapes`` restricting the corpus (exact scan).
    per_shape : int
        Corpus search: at most this many matches per shape.
    complement : bool
        Decompose the complement of ``a`` (a Geometry or path) in its bounding box.
    overlap : float in [0, 1) or None
        Non-maximum suppression by node-set overlap (Jaccard) among the pairwise
        results, and among the matches of one shape in corpus search
        (``per_shape > 1``); 0.0 (default) keeps only disjoint node sets, None
        turns suppression off.

    Returns
    -------
    list of PartMatch
        Best first.
    """
    cfg = part_config(config, hops=hops)
    qa = resolve(db, a, complement=complement, part=cfg)
    v = _query_node(qa, node, point)
    if b is not None:
        return _pairwise(qa, resolve(db, b, part=cfg), v, cfg, top=top, overlap=overlap)
    if db is None:
        raise QueryError("corpus part search needs a database", source="b=None")
    feat, qnodes = part_feature(qa.graph, v, cfg)
    return _corpus(
        db, feat, qnodes, -1 if v is None else v, cfg, k=k, where=where, per_shape=per_shape,
        overlap=_check_overlap(overlap),
    )  # fmt: skip


def _pairwise(
    qa: Any, qb: Any, v: int | None, cfg: PartConfig, *, top: int, overlap: float | None
) -> list[PartMatch]:
    """Algorithm 1 between two resolved models: the ``top`` pairs, best first."""
    vs, us, ds = match_pairs(
        qa.graph, qb.graph, config=cfg, top=top, nodes1=None if v is None else [v],
        overlap=overlap,
    )  # fmt: skip
    sets_a = node_sets(qa.graph, vs, cfg.hops)
    sets_b = node_sets(qb.graph, us, cfg.hops)
    return [
        PartMatch(
            qb.id,
            qb.name,
            qb.label,
            float(np.exp(-cfg.kernel.lam * d)),
            tuple(int(x) for x in nb),
            tuple(int(x) for x in na),
            int(u),
            int(vv),
            float(d),
        )  # fmt: skip
        for vv, u, d, na, nb in zip(vs, us, ds, sets_a, sets_b, strict=True)
    ]


def _corpus(
    db: StoreHandle,
    feat: NDArray[np.float64],
    qnodes: NDArray[np.int64],
    v: int,
    cfg: PartConfig,
    *,
    k: int,
    where: str | None,
    per_shape: int,
    overlap: float | None,
) -> list[PartMatch]:
    from query.parts.store_index import open_parts_index
    from query.search.engine import checked_k

    k = checked_k(k)  # an integer in [1, MAX_K]; the index returns at most what it holds
    index = open_parts_index(db, cfg)
    allowed = None
    if where is not None:
        from query.sql import allowed_ids

        allowed = allowed_ids(db, where)
    sids, nodes, dists = index.search(
        feat, int(k), per_shape=per_shape, allowed=allowed, overlap=overlap
    )
    names = catalog(db, db.store.version).lookup(sids)
    out = []
    for sid, u, d, found in zip(sids.tolist(), nodes.tolist(), dists.tolist(), names, strict=True):
        name, label = found if found is not None else (None, None)
        out.append(
            PartMatch(
                sid,
                name,
                label,
                float(np.exp(-cfg.kernel.lam * d)),
                tuple(int(x) for x in index.node_set(sid, u)),
                tuple(int(x) for x in qnodes),
                int(u),
                int(v),
                float(d),
            )
        )
    return out


def match_brute_force(
    db: StoreHandle,
    a: Any,
    *,
    node: int | None = None,
    point: ArrayLike | None = None,
    hops: int = 2,
    k: int = 10,
    config: PartConfig | None = None,
) -> list[PartMatch]:
    """Corpus part search without any index: Algorithm 1 against every stored shape.

    The reference for :func:`match` with ``b=None``: every stored decomposition is
    read, the neighbourhood features of all its nodes are computed node by node
    (:func:`shapedb.signature.subgraph.neighbourhood_features_naive`), and the best node of each
    shape is kept. Slow; for tests and benchmarks.
    """
    from shapedb.signature.subgraph import neighbourhood_features_naive

    cfg = part_config(config, hops=hops)
    qa = resolve(db, a, part=cfg)
    v = _query_node(qa, node, point)
    feat, qnodes = part_feature(qa.graph, v, cfg)
    w = part_weights(cfg)
    rows = []
    for sid in db.store.ids().tolist():
        rec = db.get(int(sid))
        g = part_graph(rec.decomposition, cfg)
        d = np.abs(neighbourhood_features_naive(g, cfg) - feat) @ w
        u = int(np.argmin(d))
        rows.append((float(d[u]), int(sid), u, rec, g))
    rows.sort(key=lambda t: (t[0], t[1], t[2]))
    return [
        PartMatch(
            sid,
            rec.name,
            rec.label,
            float(np.exp(-cfg.kernel.lam * d)),
            tuple(int(x) for x in g.neighbourhood(u, cfg.hops)),
            tuple(int(x) for x in qnodes),
            u,
            -1 if v is None else v,
            d,
        )
        for d, sid, u, rec, g in rows[: int(k)]
    ]


# ------------------------------------------------------------------ back to geometry
def part_geometry(
    decomposition: Any,
    nodes: ArrayLike,
    geometry: Any = None,
    *,
    tol: float | None = None,
) -> PartGeometry:
    """Balls of a part and the mesh faces or points that lie in them.

    Each face centroid (or point) is assigned to its nearest ball, by the gap
    ``|p - c| - r``; it belongs to the part when that ball is one of ``nodes`` and the
    gap is at most ``tol`` (default: the radius of that ball, i.e. within twice the
    radius of the centre; balls touch the surface only at tangent points).

    Parameters
    ----------
    decomposition : Decomposition or ContactGraph
        The balls (centres (n, 3), radii (n,)).
    nodes : (k,) int
        Ball numbers of the part (e.g. ``PartMatch.nodes``).
    geometry : TriangleMesh, PointCloud, trimesh.Trimesh or (p, 3) array, optional
        Surface to map back to.
    tol : float, optional
        Largest gap, model units.

    Returns
    -------
    PartGeometry
    """
    c = np.asarray(decomposition.centers, np.float64)
    r = np.asarray(decomposition.radii, np.float64)
    idx = np.unique(np.asarray(nodes, np.int64).ravel())
    if len(idx) and (idx[0] < 0 or idx[-1] >= len(r)):
        raise NotFoundError(f"nodes must lie in 0..{len(r) - 1}", source="nodes")
    faces = points = None
    if geometry is not None:
        verts, tris = _surface(geometry)
        if tris is not None:
            faces = _inside(verts[tris].mean(axis=1), c, r, idx, tol)
        else:
            points = _inside(verts, c, r, idx, tol)
    return PartGeometry(idx, c[idx], r[idx], faces, points)


def _surface(geometry: Any) -> tuple[NDArray[np.float64], NDArray[np.int64] | None]:
    if hasattr(geometry, "faces") and hasattr(geometry, "vertices"):
        return np.asarray(geometry.vertices, np.float64), np.asarray(geometry.faces, np.int64)
    if hasattr(geometry, "points"):
        return np.asarray(geometry.points, np.float64), None
    p = np.asarray(geometry, np.float64)
    if p.ndim == 2 and p.shape[1] == 3:
        return p, None
    raise ConfigError(
        "geometry must be a mesh, a point cloud or (p, 3) points", source=type(geometry).__name__
    )


def _inside(
    p: NDArray[np.float64],
    c: NDArray[np.float64],
    r: NDArray[np.float64],
    idx: NDArray[np.int64],
    tol: float | None,
) -> NDArray[np.int64]:
    from scipy.spatial import cKDTree

    if not len(p) or not len(idx):
        return np.zeros(0, np.int64)
    # nearest ball by gap: candidates from the k nearest centres, then the exact gap
    kq = min(16, len(r))
    _, cand = cKDTree(c).query(p, k=kq)
    cand = cand.reshape(len(p), kq)
    gap = np.linalg.norm(p[:, None, :] - c[cand], axis=2) - r[cand]
    best = np.argmin(gap, axis=1)
    ball = cand[np.arange(len(p)), best]
    g = gap[np.arange(len(p)), best]
    limit = r[ball] if tol is None else float(tol)
    return np.flatnonzero(np.isin(ball, idx) & (g <= limit)).astype(np.int64)
