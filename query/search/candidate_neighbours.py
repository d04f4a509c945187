"""Shared nearest neighbours of the stored vector, among one query's candidates.

A candidate ``x`` whose nearest stored shapes are the query's own nearest is more likely
of the query's kind than one that is merely as close: its neighbourhood agrees. With
``P`` the query ``q`` and its ``K`` nearest candidates by the stored distance ``d``
(not the query itself), ``N_k(y)`` the ``k`` nearest of ``y`` among ``P`` without
``y`` (pairwise stored distances, ``|x - y| @ w``), the score is

    S(q, x) = |({q} + N_k(q)) & ({x} + N_k(x))| / (k + 1)

and the stage's stored-distance rank ranks by ``d / d_K - beta * S`` (``d_K`` the
``K``-th candidate's distance: no unit to tune) with the nearest kept first
(:func:`query.search.lightfield_neighbours.keep_first`). Unlike the light field's
shared-neighbour term, which reads a per-store table of every stored shape's lists,
this one needs only the candidates' vectors, which the search already holds: it costs
``O(K^2 d)`` a query and nothing at commit, whatever the store's size.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.distance import pdist, squareform

__all__ = ["candidate_shared", "context_distance"]


def candidate_shared(
    d: NDArray[np.float64],
    features: NDArray[np.float64],
    query: NDArray[np.float64],
    weights: NDArray[np.float64],
    own: NDArray[np.bool_],
    k: int,
    head: int,
) -> NDArray[np.float64]:
    """(c,) ``S(q, x)`` of one query's candidates; 0 outside the ``head`` nearest.

    Parameters
    ----------
    d : (c,) float64
        Stored distances in list order (non-decreasing; inf pads are not passed).
    features : (c, n) float64
        The candidates' stored vectors (raw).
    query : (n,) float64
        The query's vector (raw).
    weights : (n,) float64
        Weights of the stored distance (``|x - y| @ weights``).
    own : (c,) bool
        The query itself among the candidates (left out of every list).
    k, head : int
        List length ``k`` >= 1 and ``K``, the nearest candidates the lists are taken among.
    """
    out = np.zeros(len(d), np.float64)
    others = np.flatnonzero(~np.asarray(own, bool))
    others = others[np.argsort(np.asarray(d)[others], kind="stable")][:head]
    m = len(others)
    if m < 2 or k < 1:
        return out
    w = np.asarray(weights, np.float64)
    xw = np.asarray(features, np.float64)[others] * w
    pair = squareform(pdist(xw, "cityblock"))  # each pair once: the same sums as cdist
    # Pool P = the query (index 0) and the head: the query is at d from each.
    full = np.empty((m + 1, m + 1))
    full[0, 0] = np.inf
    full[0, 1:] = full[1:, 0] = np.asarray(d, np.float64)[others]
    full[1:, 1:] = pair
    np.fill_diagonal(full, np.inf)
    kk = min(k, m)
    near = np.argsort(full, axis=1, kind="stable")[:, :kk]
    member = np.zeros((m + 1, m + 1), bool)
    member[np.repeat(np.arange(m + 1), kk), near.ravel()] = True
    member[np.arange(m + 1), np.arange(m + 1)] = True
    shared = (member[1:] & member[0]).sum(axis=1) / (k + 1.0)
    out[others] = shared
    return out


def context_distance(
    d: NDArray[np.float64], shared: NDArray[np.float64], own: NDArray[np.bool_], beta: float,
    head: int,
) -> NDArray[np.float64]:  # fmt: skip
    """(c,) ``d / d_K - beta * S``: ``d_K`` the ``head``-th nearest other's distance (or the
    farthest's when fewer), 1 when that is 0 or none; ``own`` entries keep ``d / d_K``."""
    d = np.asarray(d, np.float64)
    others = np.sort(d[~np.asarray(own, bool)])
    far = float(others[min(head, len(others)) - 1]) if len(others) else 0.0
    unit = far if np.isfinite(far) and far > 0 else 1.0
    return np.where(own, -np.inf, d / unit - beta * np.asarray(shared, np.float64))
