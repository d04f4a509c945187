"""Grid machinery shared by the mesh and point-cloud signed distance fields (private).

Three building blocks, each a plain function on index arrays so that a whole
128^3 grid stays well under a second:

* :func:`triangle_band` -- the narrow band of cells whose centres lie within about
  one cell of a triangle soup, found by sampling every triangle finer than half a
  cell (compiled, in rows along its longest edge) and dilating the hit cells by two.
* :func:`propagate_closest` -- closest-point propagation: given exact closest
  surface points for the band cells, every other cell takes the closest point of
  its nearest band cell (``scipy.ndimage.distance_transform_edt`` with
  ``return_indices``) and its distance to it. The result is an upper bound of the
  true distance and in practice within a few hundredths of a cell of it.
* :func:`coarse_to_fine_inside` -- point-membership classification of every cell
  from an expensive indicator (a generalised winding number) evaluated on as few
  cells as possible. The indicator is evaluated on a sub-grid of stride ``s``; a
  fine cell whose distance to the surface exceeds its distance to the nearest
  sub-grid node (plus a margin) is joined to that node by a segment that crosses
  no surface, and the winding number is continuous along it, so it inherits the
  node's classification. Only the thin shell of cells near the surface is
  evaluated directly.

Coordinates are in cell units ``u = (x - grid.origin) / grid.spacing`` unless
stated otherwise.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy import ndimage

from shapedb.geometry.base import Grid

__all__ = [
    "triangle_band",
    "cell_band",
    "propagate_closest",
    "refine_closest",
    "coarse_to_fine_inside",
    "orient_faces",
]

logger = logging.getLogger(__name__)


#: Row spacing / ``step`` in :func:`_seed_triangles`: every point of a triangle is then
#: within ``step * sqrt(2/3) / sqrt(2) = step / sqrt(3)`` of a sample.
_ROW_STEP = float(np.sqrt(2.0 / 3.0))


@njit(cache=True)
def _mark(seeds: np.ndarray, p: np.ndarray) -> None:  # pragma: no cover - compiled
    """Set the cell of point p (3,) (rounded; clamped if one cell outside, else dropped)."""
    i0, i1, i2 = int(np.rint(p[0])), int(np.rint(p[1])), int(np.rint(p[2]))
    n0, n1, n2 = seeds.shape
    if i0 < -1 or i0 > n0 or i1 < -1 or i1 > n1 or i2 < -1 or i2 > n2:
        return
    seeds[min(max(i0, 0), n0 - 1), min(max(i1, 0), n1 - 1), min(max(i2, 0), n2 - 1)] = True


@njit(cache=True)
def _seed_triangles(
    tri: np.ndarray, seeds: np.ndarray, d: float
) -> None:  # pragma: no cover - compiled
    """Mark the cells of samples of triangles (m, 3, 3), cell units, in ``seeds``.

    Samples lie on rows parallel to the longest edge AB, from AB to the opposite
    corner C, rows and samples along a row at most ``d`` apart, and on the edges AC
    and BC at most ``d`` apart: every point of the triangle is within ``d / sqrt(2)``
    of a sample (AB is the longest edge, so the rows shrink onto C without
    overhang; near the slanted edges the edge samples are the nearest).
    """
    p = np.empty(3)
    for m in range(tri.shape[0]):
        best, ia = -1.0, 0
        for e in range(3):
            s2 = 0.0
            for a in range(3):
                t = tri[m, (e + 1) % 3, a] - tri[m, e, a]
                s2 += t * t
            if s2 > best:
                best, ia = s2, e
        ib, ic = (ia + 1) % 3, (ia + 2) % 3
        A, B, C = tri[m, ia], tri[m, ib], tri[m, ic]
        length = np.sqrt(best)
        proj = 0.0
        if best > 0:
            proj = ((B - A) * (C - A)).sum() / best
        height = np.sqrt((((C - A) - proj * (B - A)) ** 2).sum())
        rows = int(np.ceil(height / d)) + 1
        for r in range(rows):
            y = r / (rows - 1) if rows > 1 else 0.0
            cols = int(np.ceil((1.0 - y) * length / d)) + 1
            for c in range(cols):
                x = c / (cols - 1) if cols > 1 else 0.0
                for a in range(3):
                    s0 = A[a] + y * (C[a] - A[a])
                    p[a] = s0 + x * (B[a] + y * (C[a] - B[a]) - s0)
                _mark(seeds, p)
        for P, Q in ((A, C), (B, C)):
            n = int(np.ceil(np.sqrt(((Q - P) ** 2).sum()) / d)) + 1
            for c in range(n):
                x = c / (n - 1) if n > 1 else 0.0
                for a in range(3):
                    p[a] = P[a] + x * (Q[a] - P[a])
                _mark(seeds, p)


def triangle_band(
    triangles: NDArray[np.float64],
    shape: tuple[int, int, int],
    *,
    step: float = 0.5,
    dilate: int = 2,
) -> NDArray[np.bool_]:
    """Cells whose centre is within about ``dilate`` cells of any triangle.

    Parameters
    ----------
    triangles : (m, 3, 3) float
        Triangle corners in cell units.
    shape : (3,) int
        Grid shape.
    step : float
        Largest lattice spacing along a triangle edge, in cells.
    dilate : int
        Chebyshev radius, in cells, of the neighbourhood of each hit cell.

    Returns
    -------
    band : shape bool
        Every cell within ``dilate`` cells (Chebyshev) of a cell holding a sample.
        Every point of a triangle is within ``step / sqrt(3)`` of a sample, so the
        band provably contains every cell whose centre is within
        ``dilate - 0.5 - step / sqrt(3)`` cells of the surface (1.21 by default).

    Notes
    -----
    Each triangle is sampled in rows parallel to its longest edge (compiled,
    :func:`_seed_triangles`), about ``area / spacing^2`` samples, so slivers cost
    their length, not its square.
    """
    seeds = np.zeros(shape, dtype=bool)
    tri = np.ascontiguousarray(triangles, dtype=np.float64)
    if len(tri):
        _seed_triangles(tri, seeds, float(step) * _ROW_STEP)
    return _dilate(seeds, dilate)


def _dilate(mask: NDArray[np.bool_], radius: int) -> NDArray[np.bool_]:
    """Chebyshev dilation by ``radius`` cells (separable: one pass per axis)."""
    if radius <= 0:
        return mask
    out = mask
    for axis in range(3):
        size = [1, 1, 1]
        size[axis] = 2 * radius + 1
        out = ndimage.maximum_filter(out, size=size, mode="constant", cval=False)
    return out


def cell_band(
    points_cells: NDArray[np.float64], shape: tuple[int, int, int], *, dilate: int = 2
) -> NDArray[np.bool_]:
    """Cells within ``dilate`` cells (Chebyshev) of a cell holding one of the points (n, 3).

    It contains every cell whose centre is within ``dilate - 0.5`` cells of a point.
    """
    seeds = np.zeros(shape, dtype=bool)
    ijk = np.rint(points_cells).astype(np.int64)
    ok = np.all((ijk >= 0) & (ijk < np.asarray(shape)), axis=1)
    ijk = ijk[ok]
    seeds[ijk[:, 0], ijk[:, 1], ijk[:, 2]] = True
    return _dilate(seeds, dilate)


def propagate_closest(
    band: NDArray[np.bool_], closest: NDArray[np.float64]
) -> tuple[NDArray[np.float32], NDArray[np.int32]]:
    """Distance of every cell to the closest point of its nearest band cell.

    Parameters
    ----------
    band : (nx, ny, nz) bool
        Narrow-band cells, at least one.
    closest : (k, 3) float
        Exact closest surface point of every band cell, in cell units, in the C order
        of ``np.flatnonzero(band)``.

    Returns
    -------
    dist : (nx, ny, nz) float32
        Distance in cells (exact on the band, an upper bound elsewhere).
    owner : (nx, ny, nz) int32
        Row of ``closest`` used by each cell.
    """
    shape = band.shape
    rank = np.full(band.size, -1, dtype=np.int32)
    flat = np.flatnonzero(band)
    rank[flat] = np.arange(len(flat), dtype=np.int32)
    ind = ndimage.distance_transform_edt(~band, return_distances=False, return_indices=True)
    nearest = (ind[0] * shape[1] + ind[1]) * shape[2] + ind[2]
    del ind
    owner = rank[nearest]
    del nearest
    dist = _distance_to(owner, closest.astype(np.float32), shape)
    return dist, owner


def _distance_to(
    owner: NDArray[np.int32], closest: NDArray[np.float32], shape: tuple[int, ...]
) -> NDArray[np.float32]:
    """|cell - closest[owner]| for every cell of ``shape`` (owner has that shape)."""
    out = np.zeros(shape, dtype=np.float32)
    for k in range(3):
        coord = np.arange(shape[k], dtype=np.float32).reshape(
            [-1 if j == k else 1 for j in range(3)]
        )
        out += (coord - closest[owner, k]) ** 2
    return np.sqrt(out, out=out)


def refine_closest(
    dist: NDArray[np.float32],
    owner: NDArray[np.int32],
    closest: NDArray[np.float64],
    cells: NDArray[np.bool_],
) -> None:
    """Lower ``dist`` in place on ``cells`` using the closest points of the 6 neighbours.

    Closest-point propagation errs where the nearest band cell is not the one that
    owns the true closest point (near the medial axis); trying the owners of the
    face neighbours halves that error. Every candidate is a real surface point, so
    the result is still an upper bound (wrap-around at the grid border is harmless).
    """
    shape = dist.shape
    idx = np.flatnonzero(cells)
    if len(idx) == 0:
        return
    ijk = np.stack(np.unravel_index(idx, shape), axis=1).astype(np.float32)
    own = owner.ravel()
    best = dist.ravel()[idx]
    cp = closest.astype(np.float32)
    n = owner.size
    for step in (shape[1] * shape[2], shape[2], 1):
        for s in (-step, step):
            c = cp[own[(idx + s) % n]]
            d = np.sqrt(((ijk - c) ** 2).sum(1))
            np.minimum(best, d, out=best)
    dist.ravel()[idx] = best


def _region_verdicts(
    far: NDArray[np.bool_],
    sub_ijk: NDArray[np.int64],
    sub_val: NDArray[np.float64],
    ambiguity: float,
) -> tuple[NDArray[np.int32], NDArray[np.int8]]:
    """The 6-connected regions of the ``far`` cells, and each region's verdict from its
    sub-grid nodes: 1 inside, -1 outside, 0 undecided (mixed, ambiguous or no node; label
    0, the near-surface shell, is always undecided)."""
    labels, n_labels = ndimage.label(far)
    node_label = labels[sub_ijk[:, 0], sub_ijk[:, 1], sub_ijk[:, 2]]
    hi = np.full(n_labels + 1, -np.inf)
    lo = np.full(n_labels + 1, np.inf)
    np.maximum.at(hi, node_label, sub_val)
    np.minimum.at(lo, node_label, sub_val)
    region = np.zeros(n_labels + 1, dtype=np.int8)
    region[lo > 0.5 + ambiguity] = 1
    region[hi < 0.5 - ambiguity] = -1
    region[np.bincount(node_label, minlength=n_labels + 1) == 0] = 0  # no node: undecided
    region[0] = 0
    return labels, region


def _inherit_from_nodes(
    dist: NDArray[np.floating],
    node_val: NDArray[np.float64],
    stride: int,
    inside: NDArray[np.bool_],
    todo: NDArray[np.bool_],
    margin: float,
    ambiguity: float,
) -> None:
    """Cells of ``todo`` farther from the surface than from their nearest sub-grid node
    (whose value ``node_val`` is unambiguous) take its classification, in place."""
    axes = [np.arange(n) for n in dist.shape]
    node = [
        np.minimum(np.rint(a / stride).astype(np.int64) * stride, ((n - 1) // stride) * stride)
        for a, n in zip(axes, dist.shape, strict=True)
    ]
    off2 = [((a - n) ** 2).astype(np.float32) for a, n in zip(axes, node, strict=True)]
    offset = np.sqrt(off2[0][:, None, None] + off2[1][None, :, None] + off2[2][None, None, :])
    val = node_val[np.ix_(*(n // stride for n in node))]
    safe = (dist > offset + margin) & (np.abs(val - 0.5) >= ambiguity)
    inherit = todo & safe
    inside[inherit] = val[inherit] > 0.5
    todo &= ~safe


def coarse_to_fine_inside(
    grid: Grid,
    dist: NDArray[np.floating],
    value: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    *,
    stride: int = 4,
    near: float = 0.75,
    margin: float = 0.5,
    ambiguity: float = 0.25,
) -> NDArray[np.bool_]:
    """Inside mask (``value > 0.5``) of every cell from few evaluations of ``value``.

    ``value`` (a generalised winding number) is evaluated on a stride-``stride``
    sub-grid and on the cells within ``near`` cells of the surface. The other cells
    (farther than 0.5 from the surface, so no surface passes between two face
    neighbours) split into 6-connected regions along which the value is continuous:

    * a region whose sub-grid nodes all agree unambiguously (closed surfaces: the
      value is constant there) takes their classification;
    * in a region with mixed or ambiguous nodes (open surfaces connect inside and
      outside through holes, and the winding number varies smoothly between them),
      a cell inherits the value of its nearest node when it is farther from the
      surface than from that node (the segment between them crosses no surface)
      and the node is unambiguous; every other cell is evaluated directly.

    Parameters
    ----------
    grid : Grid
        The grid (for model-space coordinates of the cells).
    dist : grid.shape float
        Unsigned distance to the surface, in cells: exact wherever it is below
        ``near`` (the narrow band), an upper bound elsewhere.
    value : callable
        ``value(points (n, 3) model units) -> (n,) float``, e.g. ``|winding number|``;
        inside where it exceeds 0.5. It must be continuous away from the surface.
    stride : int
        Sub-grid stride in cells.
    near : float
        Cells closer than this (>= 0.5) are evaluated directly.
    margin : float
        Safety margin in cells for the nearest-node test (``dist`` may overestimate).
    ambiguity : float
        Values within this of 0.5 are ambiguous.

    Returns
    -------
    inside : grid.shape bool
    """
    shape = grid.shape
    sub = [np.arange(0, n, stride) for n in shape]
    sx, sy, sz = np.meshgrid(*sub, indexing="ij")
    sub_ijk = np.stack([sx.ravel(), sy.ravel(), sz.ravel()], axis=1)
    sub_val = value(grid.to_point(sub_ijk))

    labels, region = _region_verdicts(dist > near, sub_ijk, sub_val, ambiguity)
    n_labels = len(region) - 1
    cell_region = region[labels]
    inside = cell_region > 0
    todo = cell_region == 0
    del labels, cell_region

    _inherit_from_nodes(dist, sub_val.reshape(sx.shape), stride, inside, todo, margin, ambiguity)
    grid_nodes = np.zeros(shape, dtype=bool)
    grid_nodes[np.ix_(*sub)] = True
    inside[grid_nodes] = sub_val > 0.5
    todo &= ~grid_nodes
    n_finer = 0
    s = stride // 2
    while s >= 2 and todo.any():  # the same inheritance from finer, nearer nodes
        n_finer += _inherit_finer(grid, dist, value, inside, todo, s, margin, ambiguity)
        s //= 2
    idx = np.argwhere(todo)
    if len(idx):
        inside[todo] = value(grid.to_point(idx)) > 0.5
    logger.debug(
        "coarse-to-fine sign: %d regions (%d undecided), %d sub-grid + %d finer-node + %d "
        "direct evaluations for %d cells", n_labels, int((region[1:] == 0).sum()),
        sub_ijk.shape[0], n_finer, len(idx), grid.size,
    )  # fmt: skip
    return inside


def _inherit_finer(
    grid: Grid,
    dist: NDArray[np.floating],
    value: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    inside: NDArray[np.bool_],
    todo: NDArray[np.bool_],
    stride: int,
    margin: float,
    ambiguity: float,
) -> int:
    """Classify ``todo`` cells (in place) from their nearest stride-``stride`` node.

    The rule of :func:`coarse_to_fine_inside` (the cell is farther from the surface
    than from the node, plus ``margin``, and the node is unambiguous) on a finer
    lattice, whose nodes are nearer; ``value`` is evaluated only at the nodes some
    cell can inherit from. Returns the number of evaluations.
    """
    shape = np.asarray(grid.shape)
    flat = np.flatnonzero(todo)
    ijk = np.stack(np.unravel_index(flat, grid.shape), axis=1)
    node = np.minimum(
        np.rint(ijk / stride).astype(np.int64) * stride, (shape - 1) // stride * stride
    )
    offset = np.sqrt(((ijk - node) ** 2).sum(axis=1))
    cand = dist.ravel()[flat] > offset + margin
    if not cand.any():
        return 0
    node_flat = np.ravel_multi_index(tuple(node[cand].T), grid.shape)
    uniq, inv = np.unique(node_flat, return_inverse=True)
    val = value(grid.to_point(np.stack(np.unravel_index(uniq, grid.shape), axis=1)))
    ok = np.abs(val - 0.5) >= ambiguity
    cells = flat[cand]
    take = ok[inv]
    inside.ravel()[cells[take]] = val[inv][take] > 0.5
    todo.ravel()[cells[take]] = False
    known = todo.ravel()[uniq]  # evaluated nodes that were still to do
    inside.ravel()[uniq[known]] = val[known] > 0.5
    todo.ravel()[uniq[known]] = False
    return len(uniq)


def orient_faces(faces: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Consistent winding inside each edge-connected component, and the component labels.

    Two faces are adjacent when they share an edge used by exactly these two faces
    (non-manifold edges join nothing). A breadth-first traversal from the lowest
    face of each component flips a face when it uses the shared edge in the same
    direction as its already oriented neighbour: ``trimesh.repair.fix_winding``'s
    rule, compiled (it is the same result on every orientable component, up to the
    component's global orientation).

    Parameters
    ----------
    faces : (m, 3) int
        Triangles (no degenerate ones).

    Returns
    -------
    faces : (m, 3) int64
        A copy, some rows reversed.
    labels : (m,) int64
        Component of each face, numbered in order of their lowest face.
    """
    f = np.ascontiguousarray(faces, dtype=np.int64)
    m = len(f)
    directed = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    lo, hi = directed.min(axis=1), directed.max(axis=1)
    key = lo * (int(f.max()) + 1) + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    start = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    count = np.diff(np.r_[start, len(ks)])
    pairs = start[count == 2]
    ea, eb = order[pairs], order[pairs + 1]  # directed-edge rows sharing an edge
    fa, fb = ea // 3, eb // 3
    keep = fa != fb
    ea, eb, fa, fb = ea[keep], eb[keep], fa[keep], fb[keep]
    same = directed[ea, 0] == directed[eb, 0]  # same direction: inconsistent pair
    src = np.concatenate([fa, fb])
    dst = np.concatenate([fb, fa])
    rel = np.concatenate([same, same])
    srt = np.argsort(src, kind="stable")
    indptr = np.searchsorted(src[srt], np.arange(m + 1))
    flip, labels = _orient_bfs(indptr, dst[srt].astype(np.int64), rel[srt], m)
    out = f.copy()
    out[flip] = out[flip][:, ::-1]
    return out, labels


@njit(cache=True)
def _orient_bfs(
    indptr: np.ndarray, nbr: np.ndarray, rel: np.ndarray, m: int
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    labels = np.full(m, -1, dtype=np.int64)
    flip = np.zeros(m, dtype=np.bool_)
    queue = np.empty(m, dtype=np.int64)
    n_labels = 0
    for root in range(m):
        if labels[root] >= 0:
            continue
        labels[root] = n_labels
        head, tail = 0, 1
        queue[0] = root
        while head < tail:
            u = queue[head]
            head += 1
            for e in range(indptr[u], indptr[u + 1]):
                v = nbr[e]
                if labels[v] < 0:
                    labels[v] = n_labels
                    flip[v] = flip[u] ^ rel[e]
                    queue[tail] = v
                    tail += 1
        n_labels += 1
    return flip, labels
