"""The greedy packing of disjoint balls on a signed distance field (the MDBD's loop).

:func:`pack_balls` repeatedly takes the grid maximum ``c = argmax F``, ``r = F(c)``,
records the ball ``(c, r)`` and carves it from the field, ``F(p) <- min(F(p), |p - c| -
r)``, until ``MDBDConfig.n_balls`` balls or the largest remaining ball is smaller than
``min_radius_cells`` cells (:mod:`shapedb.mdbd.decomposition` prepares the field and wraps the result).

**Block maxima.** The field is split into 8^3-cell blocks whose maxima are kept up to
date; the argmax scans the block maxima and one block, and a ball update touches only the
cells it can change (``|p - c| < r + max F``) and recomputes only the maxima of the blocks
it touched. Both run compiled with numba. Ties are broken by the smallest flat (C-order)
cell index, as ``numpy.argmax`` does, so the compiled loop and the plain-numpy reference
(``naive=True``) agree.
"""

from __future__ import annotations

import logging

import numpy as np
from numba import njit
from numpy.typing import NDArray

from shapedb.config.core import MDBDConfig
from shapedb.geometry.base import Geometry, Grid
from shapedb.mdbd.refine import Refiner

__all__ = ["BLOCK", "TIE_FRACTION", "TIE_TAKE", "pack_balls"]

logger = logging.getLogger(__name__)

BLOCK = 8  # edge of a block of cells in the block-max structure
#: Ties never span more than this fraction of the current maximum: on a limb a couple of
#: cells thick, ``tie_cells`` would otherwise join neighbouring parts into one "ridge".
TIE_FRACTION = 0.25
#: The cell taken from a ridge is within this fraction of the tie of the maximum.
TIE_TAKE = 0.25


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
def _first_at_least(
    F: np.ndarray, bmax: np.ndarray, B: int, thr: np.float32
) -> int:  # pragma: no cover - compiled
    """Smallest flat (C-order) index of a cell with F >= thr (found through block maxima)."""
    nx, ny, nz = F.shape
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
    return best


@njit(cache=True)
def _ridge_first(
    F: np.ndarray, start: int, thr: np.float32, top: np.float32, middle: bool
) -> int:  # pragma: no cover - compiled
    """The cell taken on the ridge: the 6-connected component of {F >= thr} holding
    ``start``. Among its cells with F >= top: the smallest flat index, or (``middle``)
    the one nearest the ridge's centroid (ties: the smallest flat index)."""
    nx, ny, nz = F.shape
    best = start
    seen = {start}
    stack = [start]
    cand = [start]
    while len(stack) > 0:
        flat = stack.pop()
        i = flat // (ny * nz)
        j = (flat // nz) % ny
        k = flat % nz
        for a in range(6):
            ii, jj, kk = i, j, k
            if a == 0:
                ii -= 1
            elif a == 1:
                ii += 1
            elif a == 2:
                jj -= 1
            elif a == 3:
                jj += 1
            elif a == 4:
                kk -= 1
            else:
                kk += 1
            if ii < 0 or jj < 0 or kk < 0 or ii >= nx or jj >= ny or kk >= nz:
                continue
            if F[ii, jj, kk] < thr:
                continue
            nb = (ii * ny + jj) * nz + kk
            if nb in seen:
                continue
            seen.add(nb)
            stack.append(nb)
            if F[ii, jj, kk] >= top:
                cand.append(nb)
                if nb < best:
                    best = nb
    if not middle:
        return best
    ci = 0.0
    cj = 0.0
    ck = 0.0
    for f in seen:
        ci += f // (ny * nz)
        cj += (f // nz) % ny
        ck += f % nz
    n = len(seen)
    ci /= n
    cj /= n
    ck /= n
    bd = np.inf
    for f in cand:
        d = (f // (ny * nz) - ci) ** 2 + ((f // nz) % ny - cj) ** 2 + (f % nz - ck) ** 2
        if d < bd - 1e-9 or (abs(d - bd) <= 1e-9 and f < best):
            bd = d
            best = f
    return best


@njit(cache=True)
def _argmax(
    F: np.ndarray, bmax: np.ndarray, B: int, tol: float, floor: float, middle: bool
) -> tuple[int, float]:  # pragma: no cover - compiled
    """The cell the greedy packing takes next: its flat index and its value.

    The maximum's first cell, then the first cell (``middle``: the cell nearest the
    ridge's centroid) within ``TIE_TAKE * tol`` of the maximum on its *ridge*: the
    6-connected cells around it within ``tol`` (at most ``TIE_FRACTION`` of the
    maximum, never below ``floor``) of the maximum. Separate local maxima are not
    tied: the best one wins, as without a tolerance.
    """
    nx, ny, nz = F.shape
    m = np.float32(-np.inf)
    for v in bmax.ravel():
        if v > m:
            m = v
    start = _first_at_least(F, bmax, B, m)
    best = start
    tol = min(tol, TIE_FRACTION * np.float64(m))
    thr = np.float32(min(max(np.float64(m) - tol, floor), np.float64(m)))
    if thr < m:
        top = np.float32(max(np.float64(m) - TIE_TAKE * (np.float64(m) - thr), np.float64(thr)))
        best = _ridge_first(F, start, thr, top, middle)
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


# -- the loop --------------------------------------------------------------------------


def _naive_argmax(
    F: NDArray[np.float32], tol: float, floor: float, middle: bool
) -> tuple[int, float]:
    """:func:`_argmax` without block maxima (the reference): scipy labels the ridge."""
    from scipy import ndimage

    m = float(F.max())
    start = int(np.argmax(F.ravel() >= np.float32(m)))
    tol = min(tol, TIE_FRACTION * m)
    thr = np.float32(min(max(m - tol, floor), m))
    flat = start
    if thr < m:
        top = np.float32(max(m - TIE_TAKE * (m - float(thr)), float(thr)))
        labels, _ = ndimage.label(F >= thr)  # 6-connected
        comp = labels.ravel() == labels.ravel()[start]
        ridge = np.flatnonzero(comp & (F.ravel() >= top))
        flat = int(ridge[0])
        if middle:
            centre = np.argwhere(comp.reshape(F.shape)).mean(axis=0)
            ijk = np.stack(np.unravel_index(ridge, F.shape), axis=1).astype(np.float64)
            d = ((ijk - centre) ** 2).sum(axis=1)
            flat = int(ridge[np.flatnonzero(d <= d.min() + 1e-9)[0]])
    return flat, float(F.ravel()[flat])


def pack_balls(
    geometry: Geometry,
    grid: Grid,
    F: NDArray[np.float32],
    cfg: MDBDConfig,
    *,
    naive: bool,
    stats: dict[str, float] | None = None,
    tail: int = 0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Run the decomposition on the field F (modified in place); balls in found order.

    ``stats``, when given, receives "refine" (seconds spent in precise queries and
    the surrogate search), "queries" (number of precise query calls) and "main" (how
    many of the returned balls are the decomposition's).

    ``tail`` > 0 continues the greedy packing after the ``cfg.n_balls`` balls (or
    after it stopped) on the same field for at most ``tail`` more balls, without
    off-grid refinement (each tail ball is its grid cell and the field's value
    there). The first ``stats["main"]`` balls are exactly those of ``tail=0``.
    """
    h = grid.spacing
    min_r = cfg.min_radius_cells * h
    tie = cfg.tie_cells * h
    middle = cfg.tie_rule == "middle"
    origin = np.asarray(grid.origin, dtype=np.float64)
    centers = np.empty((cfg.n_balls + tail, 3))
    radii = np.empty(cfg.n_balls + tail)
    n = 0
    refiner = Refiner(geometry, grid, F.copy()) if cfg.refine else None
    if naive:
        x, y, z = grid.axes()
    else:
        bmax = _block_maxima(F, BLOCK)
    main = -1
    budget = 4 * cfg.n_balls + 64  # rejections are rare; this only bounds them
    stop = cfg.n_balls
    while True:
        if n == stop or budget == 0:
            if main >= 0 or tail == 0:
                break
            main, stop, refiner_main, refiner = n, n + tail, refiner, None
            budget = tail  # the tail rejects nothing
            continue
        budget -= 1
        if naive:
            flat, top = _naive_argmax(F, tie, min_r, middle)
        else:
            flat, top = _argmax(F, bmax, BLOCK, tie, min_r, middle)
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
        if naive:
            _carve_naive(F, (x, y, z), c, r)
        else:
            _carve(F, bmax, BLOCK, origin, h, c, r, r + top + 2.0 * h)
    if main < 0:
        main, refiner_main = n, refiner
    if stats is not None:
        stats["refine"] = refiner_main.seconds if refiner_main is not None else 0.0
        stats["queries"] = float(refiner_main.queries if refiner_main is not None else 0)
        stats["main"] = float(main)
    return centers[:n], radii[:n]


def _carve_naive(
    F: NDArray[np.float32],
    axes: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
    c: NDArray[np.float64],
    r: float,
) -> None:
    """The reference carve: every cell's field becomes at most its distance to ball (c, r)."""
    x, y, z = axes
    d = (
        np.sqrt(
            (x[:, None, None] - c[0]) ** 2
            + (y[None, :, None] - c[1]) ** 2
            + (z[None, None, :] - c[2]) ** 2
        )
        - r
    )
    np.minimum(F, d.astype(np.float32), out=F)
