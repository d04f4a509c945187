"""Maximal Disjoint Ball Decomposition (MDBD) of a solid given by a :class:`Geometry`.

The paper's construction (section 2.1): compute the signed distance field ``D`` of
the solid once, on a grid; then repeatedly take the grid maximum ``c = argmax D``,
``r = D(c)``, record the ball ``(c, r)`` and remove it from the solid, which on the
field is ``D(p) <- min(D(p), |p - c| - r)``. Stop after ``n_balls`` balls or when
the largest remaining ball is smaller than ``min_radius_cells`` cells.

Two things make this fast and accurate:

* **Block maxima.** The field is split into 8^3-cell blocks whose maxima are kept
  up to date; the argmax scans the block maxima and one block, and a ball update
  touches only the cells it can change (``|p - c| < r + max D``) and recomputes
  only the maxima of the blocks it touched. Both run compiled with numba. Ties are
  broken by the smallest flat (C-order) cell index, as ``numpy.argmax`` does, so
  the fast loop and the plain-numpy reference :func:`_decompose_naive` agree.
* **Off-grid refinement** (``MDBDConfig.refine``). A grid snaps centres and radii
  to cells, which is noise: a sub-cell shift of the grid changes the features of a
  model as much as a change of pose. Each ball is therefore moved from its grid
  cell to the point (within one cell) maximising
  ``g(c) = min(D(c), min_j |c - c_j| - r_j)``. Precise distance queries are costly
  (a numpy CSG tree costs ~0.1-0.3 ms a call, a mesh's closest-point query ~10-60 us
  a point at medial points), so there is *one* query per ball: the closest boundary
  points ("witnesses") of 7 points around the cell. Near the cell,
  ``D(c) ~ min_k s_k(c)`` with ``s_k`` the signed distance to the tangent plane at
  witness ``q_k`` (exact on flat faces, second order elsewhere); this surrogate is maximised by a compiled pattern
  search down to 1/1024 cell. After the loop, one batched query gives the exact
  distance at every centre and the final radii are
  ``r_i = min(D(c_i), min_{j<i} |c_i - c_j| - r_j)`` in the order found, so the
  balls are exactly inside the solid and pairwise disjoint according to the
  representation's own distance. Signs come from the grid where it is unambiguous
  (``|D| > 1.5`` cells), else from the representation's membership test.
* **Canonical frame** (``MDBDConfig.canonical_frame``). A coarse pass (a
  ``frame_resolution`` grid over the bounding box) gives the solid's volume moments
  from smooth occupancy weights ``clip(D/h + 1/2, 0, 1)``: centroid, principal axes
  (largest variance first), axis signs from the third moments, right-handed. The
  fine grid is laid in that frame, anchored at the centroid, with ``resolution``
  cells along the longest principal extent, and the geometry is queried through
  :meth:`Geometry.transformed`. A rigid motion of the model therefore moves the
  grid with it. Centres are returned in model coordinates and the frame in
  :attr:`Decomposition.frame`. Where the frame is not determined by the moments
  (isotropic inertia: spheres, cubes, regular solids; equal pairs of moments:
  solids of revolution; symmetric axes without a third moment), the undetermined
  axes fall back to the model's axes, so ties between equally good balls are still
  broken by the grid there and a generic rotation of such a solid can change the
  decomposition (not its leading radii).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, fields, replace
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from shapedb.config import MDBDConfig
from shapedb.errors import ConfigError, DegenerateGeometryError, InvalidShapeError
from shapedb.geometry import Geometry, Grid

if TYPE_CHECKING:
    from shapedb.graph import ContactGraph

__all__ = ["Decomposition", "decompose"]

logger = logging.getLogger(__name__)

BLOCK = 8  # edge of a block of cells in the block-max structure


@dataclass(frozen=True, eq=False)
class Decomposition:
    """A truncated MDBD: balls sorted by decreasing radius, and their contacts.

    Attributes
    ----------
    centers : (n, 3) float64
        Ball centres, model units.
    radii : (n,) float64
        Ball radii, non-increasing, model units.
    edges : (m, 2) int32
        Contact-graph edges (i < j), rows sorted lexicographically.
    spacing : float
        Grid cell size used to compute the decomposition, model units.
    bounds : (2, 3) float64
        Bounding box of the source geometry.
    config : MDBDConfig
        Parameters it was computed with.
    representation : str
        Representation of the source ("mesh", "pointcloud", "voxels", "implicit", "brep").
    timings : dict[str, float]
        Seconds per stage: "frame" (coarse pass), "sdf", "decompose" (the loop,
        refinement included), "refine" (its share), "graph".
    frame : (4, 4) float64
        Homogeneous map from the grid's frame to model coordinates (rotation whose
        columns are the principal axes, and the centroid); identity without the
        canonical frame.
    """

    centers: NDArray[np.float64]
    radii: NDArray[np.float64]
    edges: NDArray[np.int32]
    spacing: float
    bounds: NDArray[np.float64]
    config: MDBDConfig = field(default_factory=MDBDConfig)
    representation: str = "unknown"
    timings: dict[str, float] = field(default_factory=dict)
    frame: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))

    @property
    def n_balls(self) -> int:
        """Number of balls n."""
        return int(len(self.radii))

    @cached_property
    def graph(self) -> ContactGraph:
        """The contact graph of the balls."""
        from shapedb.graph import ContactGraph

        return ContactGraph(self.centers, self.radii, self.edges)


# -- compiled block-max field ----------------------------------------------------------
@njit(cache=True)
def _block_maxima(F: np.ndarray, B: int) -> np.ndarray:  # pragma: no cover - compiled
    nx, ny, nz = F.shape
    out = np.full(
        ((nx + B - 1) // B, (ny + B - 1) // B, (nz + B - 1) // B), -np.inf, dtype=np.float32
    )
    for i in range(nx):
        bi = i // B
        for j in range(ny):
            bj = j // B
            for k in range(nz):
                v = F[i, j, k]
                if v > out[bi, bj, k // B]:
                    out[bi, bj, k // B] = v
    return out


@njit(cache=True)
def _recompute_blocks(
    F: np.ndarray, bmax: np.ndarray, B: int, b0: np.ndarray, b1: np.ndarray
) -> None:  # pragma: no cover - compiled
    nx, ny, nz = F.shape
    for bi in range(b0[0], b1[0] + 1):
        for bj in range(b0[1], b1[1] + 1):
            for bk in range(b0[2], b1[2] + 1):
                m = np.float32(-np.inf)
                for i in range(bi * B, min((bi + 1) * B, nx)):
                    for j in range(bj * B, min((bj + 1) * B, ny)):
                        for k in range(bk * B, min((bk + 1) * B, nz)):
                            if F[i, j, k] > m:
                                m = F[i, j, k]
                bmax[bi, bj, bk] = m


@njit(cache=True)
def _argmax(
    F: np.ndarray, bmax: np.ndarray, B: int, tol: float
) -> tuple[int, float]:  # pragma: no cover - compiled
    """Smallest flat index whose value is within ``tol`` of the maximum of F, and its value."""
    nx, ny, nz = F.shape
    m = np.float32(-np.inf)
    for v in bmax.ravel():
        if v > m:
            m = v
    thr = np.float32(np.float64(m) - tol)
    best = nx * ny * nz
    sx, sy, sz = bmax.shape
    for bi in range(sx):
        if bi * B * ny * nz > best:  # every later block starts after the best cell
            break
        for bj in range(sy):
            for bk in range(sz):
                if bmax[bi, bj, bk] < thr:
                    continue
                found = False
                for i in range(bi * B, min((bi + 1) * B, nx)):
                    for j in range(bj * B, min((bj + 1) * B, ny)):
                        for k in range(bk * B, min((bk + 1) * B, nz)):
                            if F[i, j, k] >= thr:
                                flat = (i * ny + j) * nz + k
                                if flat < best:
                                    best = flat
                                found = True
                                break
                        if found:
                            break
                    if found:
                        break
    i = best // (ny * nz)
    j = (best // nz) % ny
    return best, F[i, j, best % nz]


@njit(cache=True)
def _carve(
    F: np.ndarray,
    bmax: np.ndarray,
    B: int,
    origin: np.ndarray,
    h: float,
    c: np.ndarray,
    r: float,
    reach: float,
) -> None:  # pragma: no cover - compiled
    """F <- min(F, |p - c| - r) for cells with |p - c| < reach; refresh touched blocks."""
    nx, ny, nz = F.shape
    lo = np.empty(3, dtype=np.int64)
    hi = np.empty(3, dtype=np.int64)
    n = (nx, ny, nz)
    for a in range(3):
        lo[a] = max(int(np.floor((c[a] - reach - origin[a]) / h)), 0)
        hi[a] = min(int(np.ceil((c[a] + reach - origin[a]) / h)), n[a] - 1)
        if hi[a] < lo[a]:
            return
    reach2 = reach * reach
    for i in range(lo[0], hi[0] + 1):
        dx = (origin[0] + h * i) - c[0]
        for j in range(lo[1], hi[1] + 1):
            dy = (origin[1] + h * j) - c[1]
            dxy = dx * dx + dy * dy
            if dxy >= reach2:
                continue
            for k in range(lo[2], hi[2] + 1):
                dz = (origin[2] + h * k) - c[2]
                d2 = dxy + dz * dz
                if d2 >= reach2:
                    continue
                v = np.float32(np.sqrt(d2) - r)
                if v < F[i, j, k]:
                    F[i, j, k] = v
    _recompute_blocks(F, bmax, B, lo // B, hi // B)


# -- refinement -------------------------------------------------------------------------
# Witness samples: the cell and its six neighbours at half a cell.
_SAMPLES = np.concatenate([np.zeros((1, 3)), 0.5 * np.eye(3), -0.5 * np.eye(3)])
_SURE = 1.5  # grid |D| (cells) beyond which the grid's sign is trusted
_ROUNDS = 3  # surrogate searches per ball, each checked by one exact query
_AGREE = 0.01  # cells: surrogate and exact values this close end the search


@njit(cache=True)
def _trilinear(F: np.ndarray, origin: np.ndarray, h: float, pts: np.ndarray) -> np.ndarray:
    """Trilinear interpolation (n,) of the field F at points (n, 3), clamped to the grid."""
    # pragma: no cover - compiled
    n = pts.shape[0]
    out = np.empty(n)
    shape = F.shape
    for m in range(n):
        idx = np.empty(3, dtype=np.int64)
        fr = np.empty(3)
        for a in range(3):
            u = (pts[m, a] - origin[a]) / h
            u = min(max(u, 0.0), shape[a] - 1.000001)
            idx[a] = int(np.floor(u))
            fr[a] = u - idx[a]
        v = 0.0
        for di in range(2):
            wx = fr[0] if di else 1.0 - fr[0]
            for dj in range(2):
                wy = fr[1] if dj else 1.0 - fr[1]
                for dk in range(2):
                    wz = fr[2] if dk else 1.0 - fr[2]
                    v += wx * wy * wz * F[idx[0] + di, idx[1] + dj, idx[2] + dk]
        out[m] = v
    return out


@njit(cache=True)
def _surrogate(
    c: np.ndarray, Q: np.ndarray, N: np.ndarray, C: np.ndarray, R: np.ndarray
) -> float:  # pragma: no cover - compiled
    """min over witnesses of the distance to their tangent planes, and over balls of the gap."""
    s = np.inf
    for k in range(Q.shape[0]):
        d0, d1, d2 = c[0] - Q[k, 0], c[1] - Q[k, 1], c[2] - Q[k, 2]
        s = min(s, d0 * N[k, 0] + d1 * N[k, 1] + d2 * N[k, 2])
    for j in range(C.shape[0]):
        d0, d1, d2 = c[0] - C[j, 0], c[1] - C[j, 1], c[2] - C[j, 2]
        s = min(s, np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - R[j])
    return s


@njit(cache=True)
def _search(
    c0: np.ndarray, h: float, Q: np.ndarray, N: np.ndarray, C: np.ndarray, R: np.ndarray
) -> tuple[np.ndarray, float]:  # pragma: no cover - compiled
    """Pattern search (26 directions, halving steps) for the surrogate's maximum in c0 +- h."""
    best = c0.copy()
    bs = _surrogate(best, Q, N, C, R)
    step = 0.5 * h
    trial = np.empty(3)
    for _ in range(400):
        if step < h / 1024.0:
            break
        nb = best.copy()
        ns = bs
        for dx in range(-1, 2):
            for dy in range(-1, 2):
                for dz in range(-1, 2):
                    if dx == 0 and dy == 0 and dz == 0:
                        continue
                    trial[0] = min(max(best[0] + step * dx, c0[0] - h), c0[0] + h)
                    trial[1] = min(max(best[1] + step * dy, c0[1] - h), c0[1] + h)
                    trial[2] = min(max(best[2] + step * dz, c0[2] - h), c0[2] + h)
                    v = _surrogate(trial, Q, N, C, R)
                    if v > ns:
                        ns = v
                        nb[:] = trial
        if ns > bs + 1e-9 * h:  # a real gain, not rounding noise on a plateau
            best, bs = nb, ns
        else:
            step *= 0.5
    return best, bs


class _Refiner:
    """Off-grid refinement of balls against ``geometry`` (see the module docstring).

    ``F0`` is the grid field before any ball was carved, used for signs only.
    """

    def __init__(self, geometry: Geometry, grid: Grid, F0: NDArray[np.float32]) -> None:
        self.geometry, self.F0 = geometry, F0
        self.origin = np.asarray(grid.origin, dtype=np.float64)
        self.h = float(grid.spacing)
        self.seconds = 0.0
        self.queries = 0

    def _inside(self, pts: NDArray[np.float64]) -> NDArray[np.bool_]:
        fi = _trilinear(self.F0, self.origin, self.h, pts)
        inside = fi > 0
        unsure = np.abs(fi) < _SURE * self.h
        if unsure.any():
            inside[unsure] = self.geometry.contains(pts[unsure])
            self.queries += 1
        return inside

    def _query(
        self, pts: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Witnesses (n, 3), unit inward normals (n, 3) and exact signed distances (n,)."""
        q = np.asarray(self.geometry.closest_points(pts), dtype=np.float64)
        self.queries += 1
        sgn = np.where(self._inside(pts), 1.0, -1.0)
        v = (pts - q) * sgn[:, None]
        dist = np.linalg.norm(v, axis=1)
        n = v / np.maximum(dist, 1e-300)[:, None]
        return q, n, sgn * dist

    def ball(
        self,
        c0: NDArray[np.float64],
        depth: float,
        centers: NDArray[np.float64],
        radii: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], float]:
        """Refined centre near cell ``c0`` (grid value ``depth``) and its exact radius."""
        t0 = time.perf_counter()
        h = self.h
        q, n, d = self._query(c0 + h * _SAMPLES)
        if len(radii):
            gap0 = np.sqrt(((centers - c0) ** 2).sum(axis=1)) - radii
            near = gap0 < max(depth, 0.0) + 4.0 * h
            cn, rn = np.ascontiguousarray(centers[near]), np.ascontiguousarray(radii[near])
        else:
            cn, rn = np.zeros((0, 3)), np.zeros(0)

        def exact(c: NDArray[np.float64], dc: float) -> float:
            if len(radii):  # against every earlier ball, not only the near ones
                dc = min(dc, float((np.sqrt(((centers - c) ** 2).sum(axis=1)) - radii).min()))
            return dc

        best, best_g = c0.copy(), exact(c0, float(d[0]))
        keep = np.abs(d) > 1e-9 * h
        Q, N = q[keep], n[keep]
        for _ in range(_ROUNDS):
            c, s = _search(c0, h, np.ascontiguousarray(Q), np.ascontiguousarray(N), cn, rn)
            if np.array_equal(c, best):
                break
            qc, nc, dc = self._query(c[None])
            g = exact(c, float(dc[0]))
            if g > best_g:
                best, best_g = c, g
            if s - g <= _AGREE * h:  # the surrogate was right here: done
                break
            Q, N = np.concatenate([Q, qc]), np.concatenate([N, nc])  # learn the missed contact
        self.seconds += time.perf_counter() - t0
        return best, best_g


# -- canonical frame ---------------------------------------------------------------------
_DEGENERATE = 1e-2  # relative gap of principal moments below which their axes are a tie
_SKEW = 0.02  # |normalised third moment| below which an axis has no preferred sign


def _tie_axes(V: NDArray[np.float64], pair: tuple[int, int]) -> NDArray[np.float64]:
    """Replace the tied axes ``pair`` by model axes projected onto their plane."""
    other = ({0, 1, 2} - set(pair)).pop()
    a = V[:, other]
    e = np.eye(3)[int(np.argmin(np.abs(a)))]
    u = e - (e @ a) * a
    u /= np.linalg.norm(u)
    out = V.copy()
    out[:, pair[0]], out[:, pair[1]] = u, np.cross(a, u)
    return out


def _moments(
    geometry: Geometry, bounds: NDArray[np.float64], cfg: MDBDConfig
) -> (
    tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]
    | None
):
    """One coarse pass over ``bounds``: (axes, centroid, lo, hi, coarse cell) or None.

    ``axes`` has the principal axes as columns (largest moment first); ``lo``/``hi``
    bound the solid along them, relative to the centroid.
    """
    grid = Grid.fit(bounds, resolution=cfg.frame_resolution, padding=2)
    F = np.asarray(geometry.grid_sdf(grid), dtype=np.float64).ravel()
    hc = grid.spacing
    w = np.clip(F / hc + 0.5, 0.0, 1.0)
    mass = float(w.sum())
    if not mass > 0:
        return None
    P = grid.points()
    c = w @ P / mass
    X = P - c
    C = (X * w[:, None]).T @ X / mass
    lam, V = np.linalg.eigh(C)
    lam, V = lam[::-1].clip(min=0.0), V[:, ::-1]
    tol = _DEGENERATE * lam[0]
    if lam[0] - lam[2] <= tol:  # isotropic: no preferred axes at all
        V = np.eye(3)
    elif lam[0] - lam[1] <= tol:
        V = _tie_axes(V, (0, 1))
    elif lam[1] - lam[2] <= tol:
        V = _tie_axes(V, (1, 2))
    Y = X @ V
    skew = (w @ Y**3) / mass / np.maximum(lam, 1e-12 * lam[0] + 1e-300) ** 1.5
    for k in range(3):
        s = skew[k] if abs(skew[k]) > _SKEW else V[int(np.argmax(np.abs(V[:, k]))), k]
        if s < 0:
            V[:, k] = -V[:, k]
            skew[k] = -skew[k]
    if np.linalg.det(V) < 0:  # right-handed: flip the axis whose sign is least certain
        V[:, int(np.argmin(np.abs(skew)))] *= -1.0
    # Support of the solid along each axis: every cell bounds it by its projection
    # plus (upper side) or minus (lower side) its distance; cells near or inside only.
    near = F > -hc
    Yn, Fn = (P[near] - c) @ V, F[near][:, None]
    lo, hi = (Yn - Fn).min(axis=0), (Yn + Fn).max(axis=0)
    return V, c, lo, hi, hc


def _canonical_frame(
    geometry: Geometry, cfg: MDBDConfig
) -> (
    tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]
    | None
):
    """(rotation, centroid, local lo, local hi, coarse cell), or None if nothing is inside.

    Two coarse passes: the first on the model's axes, the second on a grid laid along
    the first estimate. The sampling error of the moments depends on how the grid
    lies on the solid; in the second pass it lies (almost) the same way whatever the
    model's orientation, so the frame's dependence on the orientation drops from
    ~0.1-0.5 degree and ~0.05 cell to second order.
    """
    first = _moments(geometry, geometry.bounds, cfg)
    if first is None:
        return None
    V1, c1, lo1, hi1, hc = first
    local = geometry.transformed(V1.T, -V1.T @ c1)
    second = _moments(local, np.stack([lo1 - hc, hi1 + hc]), cfg)
    if second is None:
        return first
    V2, c2, lo, hi, hc = second
    return V1 @ V2, c1 + V1 @ c2, lo, hi, hc


def _frame_grid(
    lo: NDArray[np.float64], hi: NDArray[np.float64], margin: float, cfg: MDBDConfig
) -> Grid:
    """Grid of the local frame: ``resolution`` cells along the longest extent, a lattice
    through the origin (the centroid), covering ``lo - margin .. hi + margin`` plus padding."""
    extent = float((hi - lo).max())
    if not extent > 0:
        raise DegenerateGeometryError(f"solid has zero extent along its principal axes: {extent}")
    h = extent / max(cfg.resolution - 2 * cfg.padding_cells, 1)
    i0 = np.floor((lo - margin) / h).astype(np.int64) - cfg.padding_cells
    i1 = np.ceil((hi + margin) / h).astype(np.int64) + cfg.padding_cells
    shape = i1 - i0 + 1
    return Grid(
        origin=h * i0.astype(np.float64),
        spacing=float(h),
        shape=(int(shape[0]), int(shape[1]), int(shape[2])),
    )


# -- the loop --------------------------------------------------------------------------
def _resolve_config(config: MDBDConfig | None, options: dict[str, Any]) -> MDBDConfig:
    cfg = config if config is not None else MDBDConfig()
    if not isinstance(cfg, MDBDConfig):
        raise ConfigError(f"config must be an MDBDConfig, got {type(cfg).__name__}")
    if options:
        unknown = set(options) - {f.name for f in fields(MDBDConfig)}
        if unknown:
            raise ConfigError(f"unknown MDBD option(s): {sorted(unknown)}")
        cfg = replace(cfg, **options)
    return cfg


def _loop(
    geometry: Geometry,
    grid: Grid,
    F: NDArray[np.float32],
    cfg: MDBDConfig,
    *,
    naive: bool,
    stats: dict[str, float] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Run the decomposition on the field F (modified in place); balls in found order.

    ``stats``, when given, receives "refine" (seconds spent in precise queries and
    the surrogate search) and "queries" (number of precise query calls).
    """
    h = grid.spacing
    min_r = cfg.min_radius_cells * h
    tie = cfg.tie_cells * h
    origin = np.asarray(grid.origin, dtype=np.float64)
    centers = np.empty((cfg.n_balls, 3))
    radii = np.empty(cfg.n_balls)
    n = 0
    refiner = _Refiner(geometry, grid, F.copy()) if cfg.refine else None
    if naive:
        x, y, z = grid.axes()
    else:
        bmax = _block_maxima(F, BLOCK)
    for _ in range(4 * cfg.n_balls + 64):  # rejections are rare; this only bounds them
        if n == cfg.n_balls:
            break
        if naive:
            thr = np.float32(float(F.max()) - tie)
            flat = int(np.argmax(F.ravel() >= thr))
            top = float(F.ravel()[flat])
        else:
            flat, top = _argmax(F, bmax, BLOCK, tie)
            flat, top = int(flat), float(top)
        if top <= 0 or top < min_r:
            break
        ijk = np.array(np.unravel_index(flat, F.shape))
        cell = origin + h * ijk
        if refiner is not None:
            c, r = refiner.ball(cell, top, centers[:n], radii[:n])
            if not (r > 0 and r >= 0.5 * min_r):  # the grid was wrong here: drop the cell
                logger.debug("rejected cell %s: refined radius %.3g", ijk.tolist(), r)
                F[tuple(ijk)] = min(top, r, 0.0) - h
                if not naive:
                    _recompute_blocks(F, bmax, BLOCK, ijk // BLOCK, ijk // BLOCK)
                continue
        else:
            c, r = cell, top
        centers[n], radii[n] = c, r
        n += 1
        reach = r + top + 2.0 * h
        if naive:
            d = (
                np.sqrt(
                    (x[:, None, None] - c[0]) ** 2
                    + (y[None, :, None] - c[1]) ** 2
                    + (z[None, None, :] - c[2]) ** 2
                )
                - r
            )
            np.minimum(F, d.astype(np.float32), out=F)
        else:
            _carve(F, bmax, BLOCK, origin, h, c, r, reach)
    centers, radii = centers[:n], radii[:n]
    if stats is not None:
        stats["refine"] = refiner.seconds if refiner is not None else 0.0
        stats["queries"] = float(refiner.queries if refiner is not None else 0)
    return centers, radii


@dataclass(frozen=True)
class _Prepared:
    local: Geometry  # the geometry in the grid's frame
    grid: Grid
    F: NDArray[np.float32]
    frame: NDArray[np.float64]  # (4, 4) local -> model
    timings: dict[str, float]


def _prepare(geometry: Geometry, cfg: MDBDConfig) -> _Prepared:
    if not isinstance(geometry, Geometry):
        raise InvalidShapeError(
            f"decompose needs a shapedb Geometry, got {type(geometry).__name__}"
        )
    timings: dict[str, float] = {}
    frame = np.eye(4)
    local = geometry
    found = None
    if cfg.canonical_frame:
        t0 = time.perf_counter()
        found = _canonical_frame(geometry, cfg)
        timings["frame"] = time.perf_counter() - t0
    if found is not None:
        V, c, lo, hi, hc = found
        grid = _frame_grid(lo, hi, 0.5 * hc, cfg)
        frame[:3, :3], frame[:3, 3] = V, c
        t0 = time.perf_counter()
        local = geometry.transformed(V.T, -V.T @ c)
        timings["frame"] += time.perf_counter() - t0
    else:
        grid = Grid.fit(geometry.bounds, resolution=cfg.resolution, padding=cfg.padding_cells)
    t0 = time.perf_counter()
    F = np.ascontiguousarray(local.grid_sdf(grid), dtype=np.float32)
    if F.shape != grid.shape:
        raise InvalidShapeError(
            f"grid_sdf returned shape {F.shape}, expected {grid.shape}", source=repr(geometry)
        )
    timings["sdf"] = time.perf_counter() - t0
    return _Prepared(local, grid, F, frame, timings)


def _finish(
    geometry: Geometry,
    prep: _Prepared,
    cfg: MDBDConfig,
    centers: NDArray[np.float64],
    radii: NDArray[np.float64],
    timings: dict[str, float],
) -> Decomposition:
    from shapedb.graph import contact_edges

    grid = prep.grid
    if len(radii) == 0:
        raise DegenerateGeometryError(
            f"no ball of radius >= {cfg.min_radius_cells} cell(s) fits inside the solid at "
            f"resolution {cfg.resolution} (cell {grid.spacing:.4g}); the solid is thinner "
            "than the grid: increase resolution",
            source=repr(geometry),
        )
    order = np.argsort(-radii, kind="stable")
    centers, radii = centers[order], radii[order]
    centers = centers @ prep.frame[:3, :3].T + prep.frame[:3, 3]  # back to model coordinates
    t0 = time.perf_counter()
    edges = contact_edges(centers, radii, cfg.contact_tol_cells * grid.spacing)
    timings["graph"] = time.perf_counter() - t0
    return Decomposition(
        centers=centers,
        radii=radii,
        edges=edges,
        spacing=float(grid.spacing),
        bounds=np.asarray(geometry.bounds, dtype=np.float64).copy(),
        config=cfg,
        representation=str(getattr(geometry, "representation", "unknown")),
        timings=timings,
        frame=prep.frame,
    )


def _run(geometry: Geometry, cfg: MDBDConfig, *, naive: bool) -> Decomposition:
    prep = _prepare(geometry, cfg)
    stats: dict[str, float] = {}
    t0 = time.perf_counter()
    centers, radii = _loop(prep.local, prep.grid, prep.F, cfg, naive=naive, stats=stats)
    timings = dict(prep.timings)
    timings["decompose"] = time.perf_counter() - t0
    timings["refine"] = stats["refine"]
    return _finish(geometry, prep, cfg, centers, radii, timings)


def decompose(
    geometry: Geometry, *, config: MDBDConfig | None = None, **options: Any
) -> Decomposition:
    """Truncated MDBD of ``geometry``, with its contact graph.

    Parameters
    ----------
    geometry : Geometry
        Any representation (mesh, point cloud, voxels, implicit...).
    config : MDBDConfig, optional
        Parameters; defaults to ``MDBDConfig()``.
    **options
        Overrides of ``config`` fields, e.g. ``resolution=64, n_balls=256``.

    Returns
    -------
    Decomposition
        Balls sorted by decreasing radius (centres in model coordinates); ``edges``
        index that order.

    Raises
    ------
    ConfigError
        For unknown or out-of-range options.
    DegenerateGeometryError
        When no ball of the minimum radius fits inside the solid.
    """
    cfg = _resolve_config(config, options)
    out = _run(geometry, cfg, naive=False)
    logger.debug("decomposed %r: %d balls, timings %s", geometry, out.n_balls, out.timings)
    return out


def _decompose_naive(
    geometry: Geometry, *, config: MDBDConfig | None = None, **options: Any
) -> Decomposition:
    """Reference implementation: full-grid argmax and full-grid update, plain numpy.

    Same results as :func:`decompose` (same frame, tie-breaking and refinement);
    used by the tests and as the baseline of ``bench/mdbd.py``.
    """
    return _run(geometry, _resolve_config(config, options), naive=True)
