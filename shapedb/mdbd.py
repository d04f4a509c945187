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
  model as much as a change of pose. Each ball is therefore refined from its grid
  cell to the point (within one cell) maximising
  ``g(c) = min(geometry.signed_distance(c), min_j |c - c_j| - r_j)`` with a
  coarse-to-fine pattern search, batched into one distance query per level; its
  radius is ``g`` there. By construction the balls are then exactly inside the
  solid and pairwise disjoint according to the representation's own distance.
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
        Seconds per stage ("sdf", "decompose", "graph").
    """

    centers: NDArray[np.float64]
    radii: NDArray[np.float64]
    edges: NDArray[np.int32]
    spacing: float
    bounds: NDArray[np.float64]
    config: MDBDConfig = field(default_factory=MDBDConfig)
    representation: str = "unknown"
    timings: dict[str, float] = field(default_factory=dict)

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
def _argmax(F: np.ndarray, bmax: np.ndarray, B: int) -> tuple[int, float]:  # pragma: no cover
    """Flat index and value of the maximum of F; ties go to the smallest flat index."""
    nx, ny, nz = F.shape
    m = np.float32(-np.inf)
    for v in bmax.ravel():
        if v > m:
            m = v
    best = nx * ny * nz
    sx, sy, sz = bmax.shape
    for bi in range(sx):
        for bj in range(sy):
            for bk in range(sz):
                if bmax[bi, bj, bk] != m:
                    continue
                found = False
                for i in range(bi * B, min((bi + 1) * B, nx)):
                    for j in range(bj * B, min((bj + 1) * B, ny)):
                        for k in range(bk * B, min((bk + 1) * B, nz)):
                            if F[i, j, k] == m:
                                flat = (i * ny + j) * nz + k
                                if flat < best:
                                    best = flat
                                found = True
                                break
                        if found:
                            break
                    if found:
                        break
    return best, m


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
_STENCIL = np.stack(np.meshgrid(*([np.arange(-1.0, 2.0)] * 3), indexing="ij"), -1).reshape(-1, 3)
# Pattern search: a 3^3 pattern of step 1/2 cell about the grid cell, then about the
# best point so far with steps 1/4, 1/8, 1/16 cell (so centres to ~1/32 cell). Few
# points per call matter for meshes, whose distance queries at medial points are slow.
_LEVELS = (0.5, 0.25, 0.125, 0.0625)


def _refine(
    geometry: Geometry,
    c0: NDArray[np.float64],
    depth: float,
    h: float,
    centers: NDArray[np.float64],
    radii: NDArray[np.float64],
) -> tuple[NDArray[np.float64], float]:
    """Centre within one cell of ``c0`` maximising g and its radius g (see module doc).

    ``depth`` is the grid's distance value at ``c0``; ``centers`` (k, 3) and ``radii``
    (k,) are the balls found so far. One batched ``signed_distance`` call per pattern
    level, none for the final radius.
    """
    if len(radii):
        gap0 = np.sqrt(((centers - c0) ** 2).sum(axis=1)) - radii
        # Only balls whose gap can fall below the solid's depth near c0 can bind
        # during the search; the final radius is checked against all of them.
        near = gap0 < max(depth, 0.0) + 4.0 * h
        cn, rn = centers[near], radii[near]
    else:
        cn, rn = centers, radii
    best, best_g = c0, -np.inf
    lo, hi = c0 - h, c0 + h
    for step in _LEVELS:
        pts = np.clip(best + (step * h) * _STENCIL, lo, hi)
        g = geometry.signed_distance(pts)
        if len(rn):
            d = np.sqrt(((pts[:, None, :] - cn[None, :, :]) ** 2).sum(axis=2)) - rn
            g = np.minimum(g, d.min(axis=1))
        i = int(np.argmax(g))
        if g[i] > best_g:
            best, best_g = pts[i], float(g[i])
    if len(radii):  # exact radius against every earlier ball, not only the near ones
        far = np.sqrt(((centers - best) ** 2).sum(axis=1)) - radii
        best_g = min(best_g, float(far.min()))
    return best.copy(), best_g


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
    geometry: Geometry, grid: Grid, F: NDArray[np.float32], cfg: MDBDConfig, *, naive: bool
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Run the decomposition on the field F (modified in place); balls in found order."""
    h = grid.spacing
    min_r = cfg.min_radius_cells * h
    origin = np.asarray(grid.origin, dtype=np.float64)
    centers = np.empty((cfg.n_balls, 3))
    radii = np.empty(cfg.n_balls)
    n = 0
    if naive:
        x, y, z = grid.axes()
    else:
        bmax = _block_maxima(F, BLOCK)
    for _ in range(4 * cfg.n_balls + 64):  # rejections are rare; this only bounds them
        if n == cfg.n_balls:
            break
        if naive:
            flat = int(np.argmax(F))
            top = float(F.ravel()[flat])
        else:
            flat, top = _argmax(F, bmax, BLOCK)
            flat, top = int(flat), float(top)
        if top <= 0 or top < min_r:
            break
        ijk = np.array(np.unravel_index(flat, F.shape))
        cell = origin + h * ijk
        if cfg.refine:
            c, r = _refine(geometry, cell, top, h, centers[:n], radii[:n])
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
    return centers[:n], radii[:n]


def _prepare(geometry: Geometry, cfg: MDBDConfig) -> tuple[Grid, NDArray[np.float32], float]:
    if not isinstance(geometry, Geometry):
        raise InvalidShapeError(
            f"decompose needs a shapedb Geometry, got {type(geometry).__name__}"
        )
    grid = Grid.fit(geometry.bounds, resolution=cfg.resolution, padding=cfg.padding_cells)
    t0 = time.perf_counter()
    F = np.ascontiguousarray(geometry.grid_sdf(grid), dtype=np.float32)
    if F.shape != grid.shape:
        raise InvalidShapeError(
            f"grid_sdf returned shape {F.shape}, expected {grid.shape}", source=repr(geometry)
        )
    return grid, F, time.perf_counter() - t0


def _finish(
    geometry: Geometry,
    grid: Grid,
    cfg: MDBDConfig,
    centers: NDArray[np.float64],
    radii: NDArray[np.float64],
    timings: dict[str, float],
) -> Decomposition:
    from shapedb.graph import contact_edges

    if len(radii) == 0:
        raise DegenerateGeometryError(
            f"no ball of radius >= {cfg.min_radius_cells} cell(s) fits inside the solid at "
            f"resolution {cfg.resolution} (cell {grid.spacing:.4g}); the solid is thinner "
            "than the grid: increase resolution",
            source=repr(geometry),
        )
    order = np.argsort(-radii, kind="stable")
    centers, radii = centers[order], radii[order]
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
    )


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
        Balls sorted by decreasing radius; ``edges`` index that order.

    Raises
    ------
    ConfigError
        For unknown or out-of-range options.
    DegenerateGeometryError
        When no ball of the minimum radius fits inside the solid.
    """
    cfg = _resolve_config(config, options)
    grid, F, t_sdf = _prepare(geometry, cfg)
    t0 = time.perf_counter()
    centers, radii = _loop(geometry, grid, F, cfg, naive=False)
    timings = {"sdf": t_sdf, "decompose": time.perf_counter() - t0}
    out = _finish(geometry, grid, cfg, centers, radii, timings)
    logger.debug("decomposed %r: %d balls, timings %s", geometry, out.n_balls, timings)
    return out


def _decompose_naive(
    geometry: Geometry, *, config: MDBDConfig | None = None, **options: Any
) -> Decomposition:
    """Reference implementation: full-grid argmax and full-grid update, plain numpy.

    Same results as :func:`decompose` (same tie-breaking, same refinement); used by
    the tests and as the baseline of ``bench/mdbd.py``.
    """
    cfg = _resolve_config(config, options)
    grid, F, t_sdf = _prepare(geometry, cfg)
    t0 = time.perf_counter()
    centers, radii = _loop(geometry, grid, F, cfg, naive=True)
    timings = {"sdf": t_sdf, "decompose": time.perf_counter() - t0}
    return _finish(geometry, grid, cfg, centers, radii, timings)
