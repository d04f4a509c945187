"""Off-grid refinement of MDBD balls against the representation's own distance (private).

A grid snaps centres and radii to cells, which is noise: a sub-cell shift of the
grid changes the features of a model as much as a change of pose does. Each ball
is therefore moved from its grid cell to the point (within one cell) maximising
``g(c) = min(D(c), min_j |c - c_j| - r_j)``.

Precise distance queries are costly (a numpy CSG tree's or a mesh's closest-point
query at medial points; ``docs/results.md``, "Ingest"), so there is *one*
query per ball: the closest boundary points ("witnesses") of 7 points around the
cell. Near the cell, ``D(c) ~ min_k s_k(c)`` with ``s_k`` the signed distance to the
tangent plane at witness ``q_k`` (exact on flat faces, second order elsewhere);
this surrogate is maximised by a compiled pattern search down to 1/1024 cell, and
checked by one exact query (up to ``_ROUNDS`` times, learning each missed contact).
The radius is exact: ``min(D(c), min_j |c - c_j| - r_j)`` against every earlier
ball, so the balls are inside the solid and pairwise disjoint according to the
representation's own distance. Signs come from the grid where it is unambiguous
(``|D| > 1.5`` cells), else from the representation's membership test.
"""

from __future__ import annotations

import time

import numpy as np
from numba import njit
from numpy.typing import NDArray

from shapedb.geometry.base import Geometry, Grid

__all__ = ["Refiner"]

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


class Refiner:
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
