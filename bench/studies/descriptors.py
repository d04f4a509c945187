"""Prototype descriptors computed only from MDBD balls and their contact graph.

Everything here is a bench prototype: the winner moves into the library afterwards.
Each *block* maps a decomposition (:class:`bench.common.Balls`) to a fixed-length
vector compared with L1; 1-D distributions are stored as CDFs, so that L1 between
them is the 1-D Wasserstein (earth mover's) distance and small shifts of a value
move the distance a little instead of jumping between bins.

Scale: every length is divided by ``s = (sum r_i^3)^(1/3)``, the cube root of the
balls' total volume (up to 4 pi / 3); unlike the largest radius r1, it does not hinge
on one ball. Weights: balls count by volume ``v_i = r_i^3 / sum r^3``, so the many
small balls (whose number depends on resolution and the ball budget) carry little.

Blocks
------
``radius``     CDF of log2(r/s), volume-weighted.
``radius_n``   CDF of log2(r/s), count-weighted.
``d2c``        D2 on ball centres: CDF of |ci - cj| / s, weights v_i v_j (rotation invariant).
``d2c_mean``   same, distances normalised by their weighted mean (as Osada's D2).
``d1c``        CDF of the distance of each centre from the volume centroid, / s.
``inertia``    sorted eigenvalues of the union's second moments, / s^2 (3 values, sqrt).
``degree``     volume-weighted histogram of contact degrees 0..15+.
``spectrum``   heat trace (1/n) sum exp(-tau lambda) of the normalised Laplacian, 12 tau.
``wwl``        WWL-style: x^0 = log2(r/s), x^(h+1) = (x^h + mean of neighbours) / 2;
               volume-weighted CDFs of x^1..x^3 (x^0 is ``radius``).
``walk``       the paper's walk averages at t = 1, 3, 10 as volume-weighted CDFs.
``paper``      the paper's Eq. 1 vector (n_r = 32, t = 10, w = 0.9), weighted by Eq. 2.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from bench.common import Balls
from bench.support.features import l1_matrix

__all__ = [
    "BLOCKS",
    "block",
    "block_scales",
    "paper_features",
    "describe",
    "combined_distance",
    "l1_matrix",
]

FloatArray = NDArray[np.float64]

_LOG_BINS = np.linspace(-7.0, 0.5, 31)
_DIST_BINS = np.linspace(0.0, 4.0, 41)
_MEAN_BINS = np.linspace(0.0, 3.0, 31)


def _cdf(values: FloatArray, weights: FloatArray, edges: FloatArray) -> FloatArray:
    h, _ = np.histogram(np.clip(values, edges[0], edges[-1]), bins=edges, weights=weights)
    total = h.sum()
    c = np.cumsum(h) / total if total > 0 else np.zeros(len(h))
    # Scale by the bin width so that L1 of CDFs approximates the 1-D Wasserstein distance.
    return c * (edges[1] - edges[0])


def _scale(b: Balls) -> float:
    return float(np.cbrt((b.radii**3).sum()))


def _vol(b: Balls) -> FloatArray:
    v = b.radii**3
    return v / v.sum()


def _adjacency(b: Balls) -> sp.csr_matrix:
    n = len(b.radii)
    e = b.edges
    a = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    return (a + a.T).tocsr()


def _radius(b: Balls) -> FloatArray:
    return _cdf(np.log2(b.radii / _scale(b)), _vol(b), _LOG_BINS)


def _radius_n(b: Balls) -> FloatArray:
    return _cdf(np.log2(b.radii / _scale(b)), np.ones(len(b.radii)), _LOG_BINS)


def _pair_distances(b: Balls, limit: int = 400) -> tuple[FloatArray, FloatArray]:
    c, v = b.centers[:limit], _vol(b)[:limit]
    iu = np.triu_indices(len(c), 1)
    d = np.linalg.norm(c[iu[0]] - c[iu[1]], axis=1)
    return d, v[iu[0]] * v[iu[1]]


def _d2c(b: Balls) -> FloatArray:
    d, w = _pair_distances(b)
    return _cdf(d / _scale(b), w, _DIST_BINS)


def _d2c_mean(b: Balls) -> FloatArray:
    d, w = _pair_distances(b)
    mean = float((d * w).sum() / max(w.sum(), 1e-300))
    return _cdf(d / max(mean, 1e-300), w, _MEAN_BINS)


def _d1c(b: Balls) -> FloatArray:
    v = _vol(b)
    g = (b.centers * v[:, None]).sum(axis=0)
    return _cdf(np.linalg.norm(b.centers - g, axis=1) / _scale(b), v, _DIST_BINS[:31] * 0.75)


def _inertia(b: Balls) -> FloatArray:
    v = _vol(b)
    g = (b.centers * v[:, None]).sum(axis=0)
    x = b.centers - g
    # Second moments of the balls: point mass at the centre plus the ball's own 0.2 r^2 I.
    m = (x * v[:, None]).T @ x + np.eye(3) * float((0.2 * b.radii**2 * v).sum())
    ev = np.sort(np.linalg.eigvalsh(m))[::-1]
    return np.sqrt(np.maximum(ev, 0.0)) / _scale(b)


def _degree(b: Balls) -> FloatArray:
    deg = np.asarray(_adjacency(b).sum(axis=1)).ravel()
    h = np.bincount(np.minimum(deg, 15).astype(np.int64), weights=_vol(b), minlength=16)
    return h / max(h.sum(), 1e-300)


_TAUS = np.geomspace(0.1, 30.0, 12)


def _spectrum(b: Balls) -> FloatArray:
    a = _adjacency(b).toarray()
    d = a.sum(axis=1)
    inv = np.where(d > 0, 1.0 / np.sqrt(np.maximum(d, 1e-300)), 0.0)
    lap = np.diag((d > 0).astype(np.float64)) - inv[:, None] * a * inv[None, :]
    lam = np.clip(np.linalg.eigvalsh(lap), 0.0, 2.0)
    return np.exp(-_TAUS[:, None] * lam[None, :]).mean(axis=1)


def _neighbour_mean(a: sp.csr_matrix, x: FloatArray) -> FloatArray:
    deg = np.asarray(a.sum(axis=1)).ravel()
    s = a @ x
    return np.where(deg > 0, s / np.maximum(deg, 1), x)


def _wwl(b: Balls, hops: int = 3) -> FloatArray:
    a = _adjacency(b)
    x = np.log2(b.radii / _scale(b))
    v = _vol(b)
    out = []
    for _ in range(hops):
        x = 0.5 * (x + _neighbour_mean(a, x))
        out.append(_cdf(x, v, _LOG_BINS))
    return np.concatenate(out)


def _walk(b: Balls, w: float = 0.9, ts: Sequence[int] = (1, 3, 10)) -> FloatArray:
    a = _adjacency(b)
    deg = np.asarray(a.sum(axis=1)).ravel()
    t_mat = a @ sp.diags(np.where(deg > 0, 1.0 / np.maximum(deg, 1), 0.0))
    p = b.radii / b.radii[0]
    acc = np.zeros_like(p)
    v = _vol(b)
    out = []
    for k in range(1, max(ts) + 1):
        p = t_mat @ p
        acc += w**k * p
        if k in ts:
            out.append(_cdf(np.log2(np.maximum(acc / k, 1e-6)), v, np.linspace(-12, 0.5, 31)))
    return np.concatenate(out)


def paper_features(
    b: Balls, *, n_r: int = 32, t: int = 10, w: float = 0.9, la: float = 0.75, lb: float = 0.75
) -> FloatArray:
    """Eq. 1 of the paper, pre-multiplied by the Eq. 2 weights (so plain L1 is Eq. 2).

    p^0 = r / r1 for every ball, p^k = A p^(k-1) with A column-stochastic (1/deg(j)
    on each edge), P_i = (1/t) sum_k w^k p_i^k; the first ``n_r`` balls, zero-padded.
    """
    a = _adjacency(b)
    deg = np.asarray(a.sum(axis=1)).ravel()
    t_mat = a @ sp.diags(np.where(deg > 0, 1.0 / np.maximum(deg, 1), 0.0))
    p0 = b.radii / b.radii[0]
    p = p0.copy()
    acc = np.zeros_like(p)
    for k in range(1, t + 1):
        p = t_mat @ p
        acc += w**k * p
    f = np.zeros(2 * n_r)
    m = min(n_r, len(p0))
    f[:m] = p0[:m]
    f[n_r : n_r + m] = acc[:m] / t
    weights = np.concatenate([la ** np.arange(1, n_r + 1), lb ** np.arange(1, n_r + 1)])
    return f * weights


#: Every prototype block, by name.
BLOCKS: dict[str, Callable[[Balls], FloatArray]] = {
    "radius": _radius,
    "radius_n": _radius_n,
    "d2c": _d2c,
    "d2c_mean": _d2c_mean,
    "d1c": _d1c,
    "inertia": _inertia,
    "degree": _degree,
    "spectrum": _spectrum,
    "wwl": _wwl,
    "walk": _walk,
    "paper": paper_features,
}


def block(name: str, b: Balls) -> FloatArray:
    """One block of one decomposition."""
    return np.asarray(BLOCKS[name](b), dtype=np.float64)


def describe(balls: Sequence[Balls], names: Sequence[str] = tuple(BLOCKS)) -> dict[str, FloatArray]:
    """Blocks of many decompositions: ``{name: (n_models, d)}``."""
    return {n: np.stack([block(n, b) for b in balls]) for n in names}


def block_scales(blocks: Mapping[str, FloatArray]) -> dict[str, float]:
    """Typical distance of each block: the median L1 distance over pairs of models."""
    out = {}
    for name, x in blocks.items():
        d = l1_matrix(x, x)
        iu = np.triu_indices(len(x), 1)
        out[name] = float(np.median(d[iu])) or 1.0
    return out


def combined_distance(
    queries: Mapping[str, FloatArray],
    database: Mapping[str, FloatArray],
    weights: Mapping[str, float],
    scales: Mapping[str, float],
) -> FloatArray:
    """Weighted sum of per-block L1 distances, each divided by its scale.

    Parameters
    ----------
    queries, database : mapping name -> (n, d) / (m, d)
        Blocks of the query and database models.
    weights : mapping name -> float
        Blocks that enter, and their weights.
    scales : mapping name -> float
        Typical distance of each block (e.g. the median over validation pairs),
        so that weights are comparable across blocks.
    """
    total: FloatArray | None = None
    for name, w in weights.items():
        d = l1_matrix(queries[name], database[name]) * (w / scales[name])
        total = d if total is None else total + d
    assert total is not None
    return total
